"""No multisampling where the page's WebGL is drawn in software: frame rate before smooth edges.

A machine without a usable GPU draws WebGL on its CPU (Chromium: SwiftShader; Firefox and other
Mesa users: llvmpipe or softpipe; Windows: the Basic Render Driver). There, every frame of the
3-D view costs tens of milliseconds, and 4x multisampling (three.js asks for it) is about a
quarter of that: at 1366 x 768 on a loaded 2-core machine the page drew 7.5 frames/s while the
arm moved, 10.3 without multisampling (``benchmarks/page_fps.py``, benchmarks/README.md). A
teleoperated arm that moves in jerks is a worse confound than edges stepped by a pixel.

:data:`SOFTWARE_WEBGL_SCRIPT` goes into the participant page's head (``study.server.page_head``),
so it runs before viser's client asks for its WebGL context: it asks the browser once which
renderer draws WebGL (``WEBGL_debug_renderer_info``, else ``RENDERER``) and, on a software
renderer only, requests the context without antialiasing. With a GPU the page is unchanged.
"""

from __future__ import annotations

SOFTWARE_RENDERERS = r"swiftshader|llvmpipe|softpipe|basic render driver"
"""Renderer names (a case-blind regular expression) of WebGL drawn on the CPU."""

SOFTWARE_WEBGL_SCRIPT = (
    r"""<script>(() => {
  const cpu = /__RENDERERS__/i;
  const get = HTMLCanvasElement.prototype.getContext;
  let onCpu = null;
  const probe = () => {
    try {
      const gl = get.call(document.createElement("canvas"), "webgl");
      if (!gl) return false;
      const info = gl.getExtension("WEBGL_debug_renderer_info");
      const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
      const lose = gl.getExtension("WEBGL_lose_context");
      if (lose) lose.loseContext();
      return cpu.test(name);
    } catch (e) {
      return false;
    }
  };
  HTMLCanvasElement.prototype.getContext = function (kind, options) {
    if (kind === "webgl2" || kind === "webgl") {
      if (onCpu === null) onCpu = probe();
      if (onCpu) options = Object.assign({}, options || {}, { antialias: false });
    }
    return get.call(this, kind, options);
  };
})();</script>"""
).replace("__RENDERERS__", SOFTWARE_RENDERERS)


__all__ = ["SOFTWARE_RENDERERS", "SOFTWARE_WEBGL_SCRIPT"]

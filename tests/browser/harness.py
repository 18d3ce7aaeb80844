"""Playwright helpers shared by the browser tests and benchmarks/server.py.

Chromium is Debian's (``/usr/bin/chromium``), never a downloaded one. viser sends each window
of messages as one binary websocket frame: two little-endian uint64 (msgpack size, compressed
size), the zstd-compressed msgpack ``{"messages": [...], ...}``, then raw binary buffers;
:func:`decode_frame` returns the message dicts.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import msgspec
import numpy as np
import viser
import viser.transforms as vtf
import zstandard

from tests.protocol_copies import PAPER_PROTOCOL
from tests.protocol_copies import short_protocol as copy

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]
"""Chromium's flags. None that keeps the picture cuts its CPU (measured 2026-12-04 with
``benchmarks/chromium_cpu.py`` and a page held in a run, the arm steered by held keys, 15 s
windows, paired runs): while the arm moves 50 % of Chromium's CPU is SwiftShader running the
page's shaders (``gpu / Thread<NN>``, 69 % of the GPU process in JIT code by ``perf``; it
scales with the canvas's pixels: 29 % of them -> 48 %), not spinning: one SwiftShader thread
instead of two (``SwiftShader.ini`` beside the Chromium binary) does the same work, 4.5-5.6 CPU s
against 4.6-5.6 (Chromium 9.2-10.8 against 9.5-10.4, 4 pairs). ``--in-process-gpu``: 9.5-10.5
against 9.1-10.7 (3 pairs); GPU compositing through SwiftShader (no ``--disable-gpu``,
``--use-angle=swiftshader``): 16.1 against 9.5 (one pair). An idle page draws about once a
second (on demand), so pages left open cost little."""


FRAME_CAP_FPS = float(os.environ.get("TEST_FRAME_CAP", "10"))
"""Frames a second the tests' pages draw at most (``TEST_FRAME_CAP=0``: no cap). Software WebGL
draws as fast as the CPU lets it while the arm moves, near a core a page, CPU the suite's other
workers need (issue 24.4). 10 a second is what a weak laptop draws the page at (9-15 measured
under load), so every test's behaviour is one a participant can meet; the page's own frame
rate is measured uncapped by ``benchmarks/page_fps.py``. Measured in one session, paired runs:
``test_depth_and_limits.py`` Chromium 80.9 -> 50.7 CPU s, ``test_keys_and_pause.py`` 19.7 ->
14.9; both browser lanes (``-n 2``, helpers' jobs on the machine) 345 -> 287 CPU s of
Chromium."""

FRAME_CAP_JS = """
(() => {
  const period = 1000 / __FPS__;
  if (!(period > 0) || !isFinite(period)) return;
  const frame = window.requestAnimationFrame.bind(window);
  const queue = new Map();
  let next = 1, asked = false, last = -1e9;
  const run = (t) => {
    if (t - last < period - 2) { frame(run); return; }
    asked = false;
    last = t;
    const due = [...queue.values()];
    queue.clear();
    for (const cb of due) {
      try { cb(t); } catch (e) { queueMicrotask(() => { throw e; }); }
    }
  };
  window.requestAnimationFrame = (cb) => {
    const id = next++;
    queue.set(id, cb);
    if (!asked) { asked = true; frame(run); }
    return id;
  };
  window.cancelAnimationFrame = (id) => { queue.delete(id); };
})();
"""


def new_context(browser: Any, **options: Any) -> Any:
    """``browser.new_context(**options)`` whose pages draw at most :data:`FRAME_CAP_FPS` frames
    a second: ``requestAnimationFrame`` callbacks wait for the frame after a period has passed
    (viser's drawing, the page script's resends and the tests' own frame waits alike)."""
    ctx = browser.new_context(**options)
    if FRAME_CAP_FPS > 0:
        ctx.add_init_script(FRAME_CAP_JS.replace("__FPS__", repr(FRAME_CAP_FPS)))
    return ctx


MESA_EGL = Path("/usr/share/glvnd/egl_vendor.d/50_mesa.json")
"""Mesa's EGL (Debian's ``libegl-mesa0``, installed by ``.ci/setup``): llvmpipe behind it."""

LLVMPIPE_ARGS = [
    *(a for a in CHROMIUM_ARGS if a != "--disable-gpu"),
    "--use-gl=angle",
    "--use-angle=gl-egl",
    "--ignore-gpu-blocklist",
    "--disable-gpu-compositing",
]
"""WebGL drawn by Mesa's llvmpipe (ANGLE on EGL) instead of SwiftShader, the page composited in
software as with ``--disable-gpu``. The same scene in the same pixels for 29 % less of
Chromium's CPU at 1366 x 768 (``test_depth_and_limits.py``: GPU process 46.4 -> 22.7 CPU s,
Chromium 74.8 -> 53.4) and 17-33 % less at 1100 x 720 (``test_keys_and_pause.py``: 22.5 and 27.9
-> 18.7 twice; measured 2026-12-04 with ``benchmarks/chromium_cpu.py``). GPU compositing through
llvmpipe too (without ``--disable-gpu-compositing``) cost more: 25.4. The tests' browser (issue
24.4: Chromium's drawing was 43 % of the suite's CPU); a participant's laptop without a GPU
draws with SwiftShader, so the page's benchmarks (``page_fps.py``) keep it."""

WebGL = Literal["swiftshader", "llvmpipe"]
TEST_WEBGL: WebGL = "swiftshader" if os.environ.get("TEST_WEBGL") == "swiftshader" else "llvmpipe"
"""The tests' WebGL (``TEST_WEBGL=swiftshader``: Chromium's own, as the benchmarks draw)."""


class WebGLUnavailable(RuntimeError):
    """The WebGL asked for cannot be drawn on this machine."""


def launch(playwright: Any, *, webgl: WebGL = "swiftshader") -> Any:
    """Start headless Debian Chromium, its WebGL drawn by SwiftShader (a laptop without a GPU)
    or by Mesa's llvmpipe (:data:`LLVMPIPE_ARGS`)."""
    if webgl == "llvmpipe" and not MESA_EGL.exists():
        raise WebGLUnavailable(
            f"llvmpipe WebGL needs Mesa's EGL ({MESA_EGL} missing): run `bash .ci/setup` as root"
            " (installs libegl-mesa0 and libgl1-mesa-dri) or set TEST_WEBGL=swiftshader"
        )
    args = LLVMPIPE_ARGS if webgl == "llvmpipe" else CHROMIUM_ARGS
    return playwright.chromium.launch(executable_path=CHROMIUM, args=args, headless=True)


WEBGL_RENDERER_JS = """() => {
  const gl = document.createElement('canvas').getContext('webgl2');
  if (!gl) return '';
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}"""


def webgl_renderer(browser: Any) -> str:
    """The renderer string a page of ``browser`` gets for WebGL 2 ('' when it gets none)."""
    page = browser.new_page()
    try:
        return str(page.evaluate(WEBGL_RENDERER_JS))
    finally:
        page.close()


def decode_frame(payload: bytes | str) -> list[dict[str, Any]]:
    """Messages carried by one viser websocket frame (server to browser)."""
    if isinstance(payload, str):
        return []
    inner_len = int.from_bytes(payload[0:8], "little")
    comp_len = int.from_bytes(payload[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(
        payload[16 : 16 + comp_len], max_output_size=inner_len
    )
    decoded = msgspec.msgpack.decode(inner)
    return list(decoded.get("messages", ()))


def iter_strings(obj: Any) -> Iterator[str]:
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(k, str):
                yield k
            yield from iter_strings(v)
    elif isinstance(obj, list | tuple):
        for v in obj:
            yield from iter_strings(v)


@dataclass
class FrameLog:
    """Every frame a page's websockets received, with its arrival time (thread-safe)."""

    frames: list[tuple[float, bytes]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def attach(self, page: Any) -> FrameLog:
        def on_ws(ws: Any) -> None:
            def on_frame(payload: Any) -> None:
                if isinstance(payload, bytes | bytearray):
                    with self.lock:
                        self.frames.append((time.monotonic(), bytes(payload)))

            ws.on("framereceived", on_frame)

        page.on("websocket", on_ws)
        return self

    def messages(self) -> list[dict[str, Any]]:
        with self.lock:
            frames = list(self.frames)
        out: list[dict[str, Any]] = []
        for _, payload in frames:
            out.extend(decode_frame(payload))
        return out

    def strings(self) -> list[str]:
        return [s for m in self.messages() for s in iter_strings(m)]

    def raw_bytes(self) -> bytes:
        """Every frame's decompressed msgpack plus its binary buffers (meshes, arrays),
        lower-cased: what a byte-level search for a word must look through."""
        with self.lock:
            frames = [payload for _, payload in self.frames]
        parts = []
        for payload in frames:
            inner_len = int.from_bytes(payload[0:8], "little")
            comp_len = int.from_bytes(payload[8:16], "little")
            inner = zstandard.ZstdDecompressor().decompress(
                payload[16 : 16 + comp_len], max_output_size=inner_len
            )
            parts.append(inner + payload[16 + comp_len :])
        return b"\n".join(parts).lower()


def project(camera: viser.CameraHandle, point: np.ndarray) -> tuple[float, float]:
    """Pixel (x, y) of world ``point`` in ``camera``'s image (OpenCV camera axes)."""
    rot = vtf.SO3(np.asarray(camera.wxyz)).as_matrix()
    pc = rot.T @ (np.asarray(point, float) - np.asarray(camera.position))
    f = (camera.image_height / 2) / np.tan(camera.fov / 2)
    return (
        float(f * pc[0] / pc[2] + camera.image_width / 2),
        float(f * pc[1] / pc[2] + camera.image_height / 2),
    )


def drag(page: Any, start: tuple[float, float], end: tuple[float, float], *, steps: int = 12):
    """Press at ``start``, move to ``end`` in ``steps`` moves, release.

    Software WebGL draws a few frames per second under load, and the gizmo is picked on
    pointer events: hover first (small moves), then move slowly enough for each move to land.
    """
    page.mouse.move(start[0] - 6, start[1] + 6)
    page.wait_for_timeout(300)
    page.mouse.move(start[0] - 2, start[1] + 2)
    page.wait_for_timeout(300)
    page.mouse.move(*start)
    page.wait_for_timeout(500)
    page.mouse.down()
    page.wait_for_timeout(500)
    for k in range(1, steps + 1):
        a = k / steps
        page.mouse.move(start[0] + a * (end[0] - start[0]), start[1] + a * (end[1] - start[1]))
        page.wait_for_timeout(150)
    page.wait_for_timeout(400)
    page.mouse.up()


def drag_until(
    page: Any,
    start: tuple[float, float],
    end: tuple[float, float],
    moved: Any,
    *,
    steps: int = 12,
    tries: int = 2,
    timeout: float = 10.0,
) -> bool:
    """Drag from ``start`` to ``end`` until ``moved()`` holds, as a person who missed the
    handle tries again: software WebGL under load can pick nothing on the first press."""
    for _ in range(tries):
        drag(page, start, end, steps=steps)
        if wait_until(moved, timeout=timeout):
            return True
    return False


def wait_until(predicate: Any, *, timeout: float = 20.0, interval: float = 0.05) -> bool:
    """Poll ``predicate()`` until truthy or ``timeout`` seconds pass; return its last value."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() > deadline:
            return bool(value)
        time.sleep(interval)


def wait_still(
    read: Any,
    *,
    tol: float = 5e-4,
    still_s: float = 0.25,
    timeout: float = 10.0,
    interval: float = 0.05,
) -> bool:
    """Poll ``read()`` (numbers) until it has stayed within ``tol`` (each number) for ``still_s``
    seconds: a held key's release or a drag's end has landed and what follows it has come to
    rest -- awaited, not a fixed wait that a loaded machine outlasts. False after ``timeout``."""
    ref = np.asarray(read(), float)
    since = now = time.monotonic()
    deadline = now + timeout
    while now < deadline:
        time.sleep(interval)
        value, now = np.asarray(read(), float), time.monotonic()
        if np.abs(value - ref).max() > tol:
            ref, since = value, now
        elif now - since >= still_s:
            return True
    return False


# -- a study server on free ports, with a shortened copy of the paper's protocol -----------------


def short_protocol(
    directory: Any,
    *,
    time_limit_s: float = 6.0,
    training_runs: int = 1,
    source: Path = PAPER_PROTOCOL,
    asked_once: bool = False,
) -> Any:
    """A copy of the protocol ``source`` (the paper's by default) with short trials and
    ``training_runs`` practice runs, so a test walks through every kind of screen quickly."""
    return copy(
        directory,
        time_limit_s=time_limit_s,
        training_runs=training_runs,
        source=source,
        asked_once=asked_once,
    )


@dataclass
class RunningServer:
    server: Any
    store: Any
    protocol: Any

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server.participant_port}"

    @property
    def console_url(self) -> str:
        return f"http://127.0.0.1:{self.server.experimenter_port}"

    def stop(self) -> bool:
        """Stop the server, close the store; whether the server's threads ended."""
        ended = self.server.stop()
        self.store.close()
        return ended


SERVER_DEFAULTS: dict[str, Any] = {}
"""``StudyServer`` options :func:`start_server` passes unless ``server_kw`` says otherwise
(``tests/conftest.py`` sets the tests' own; the benchmarks keep the server's defaults)."""


def start_server(
    directory: Any,
    *,
    host: str = "127.0.0.1",
    server_kw: dict[str, Any] | None = None,
    edit: Any = None,
    **protocol_kw: Any,
) -> RunningServer:
    """A ``StudyServer`` on free ports over a fresh store in ``directory`` (``server_kw`` go
    to the ``StudyServer``, e.g. ``kiosk=True``; ``edit(path)`` may change the protocol copy
    first, e.g. ``tests.protocol_copies.with_completion``)."""
    from study.protocol import load_protocol
    from study.server.live import session_factory
    from study.server.server import StudyServer
    from study.session import open_store

    path = short_protocol(directory, **protocol_kw)
    protocol = load_protocol(edit(path) if edit is not None else path)
    store = open_store(Path(directory) / "study.db", protocol)
    server = StudyServer(
        session_factory(store, protocol),
        condition_words=protocol.condition_words,
        host=host,
        port=0,
        experimenter_port=0,
        **{**SERVER_DEFAULTS, **(server_kw or {})},
    )
    return RunningServer(server, store, protocol)


def run_async(coro: Any) -> Any:
    """``asyncio.run(coro)`` in a fresh thread: works even when the calling thread already
    runs an event loop (sync Playwright keeps one alive while a browser fixture is open)."""
    import asyncio

    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["value"] = asyncio.run(coro)
        except BaseException as exc:
            box["error"] = exc

    thread = threading.Thread(target=target, name="run-async")
    thread.start()
    thread.join()
    if "error" in box:
        raise box["error"]
    return box.get("value")

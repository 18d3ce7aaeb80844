"""The handle's poses reach the server while the page is busy drawing: part of the page script.

viser's client sends a drag's poses through a 50 ms throttle: the first pose at once, the
newest one when a 50 ms timer fires. A page whose main thread is busy drawing (software WebGL
on a loaded machine: a frame every 150-1000 ms) runs that timer after the next frame or later
-- 330 ms late in the median and up to 1.25 s under a test run's load, 2.3 s without a single
pose once (``benchmarks/page_drag.py``) -- while the pointer's own events still reach the page
every frame and move the handle on the screen. The arm stood still while the handle moved.

This script sends the handle's newest pose from the page's frames when viser's sender is
overdue: while a handle is dragged (from viser's drag-start message until its drag-end or the
pointer's button going up anywhere on the page -- a pause hides the handle mid-drag, and viser
then never ends the drag), each
frame (``requestAnimationFrame``: frames are the page's own pace, and the browser hands it the
pointer's events at the start of each frame, so the handle has moved already), if no pose of
it went out for :data:`HANDLE_OVERDUE_MS` and the pose the page shows differs from the last one
sent, it is sent -- the same message viser sends, through viser's channel. With the timer on
time (an idle machine) nothing is added: viser's sender is never overdue. The page
shows the same; only the server hears of each pose sooner. Every message carries the newest
pose at the time it is sent, so the server never receives an older pose after a newer one.
"""

from __future__ import annotations

import json

from study.server import viser_door

VISER_THROTTLE_MS = 50.0
"""viser's client sends a drag's poses at most this often (``makeThrottledMessageSender``)."""

HANDLE_OVERDUE_MS = 2 * VISER_THROTTLE_MS
"""No pose of the dragged handle sent for this long while the page shows a newer one: viser's
timer is late, and the next frame sends the pose instead."""


def handle_pace_script() -> str:
    """JavaScript (installed once per page load, with the rest of the page script)."""
    return _TEMPLATE.replace("__VISER__", viser_door.CLIENT_GLOBAL).replace(
        "__OVERDUE__", json.dumps(HANDLE_OVERDUE_MS)
    )


_TEMPLATE = r"""
(() => {
  const m = __VISER__;
  if (!m || m.__studyHandlePace) return;
  const drag = m.__studyHandlePace = {name: null, owner: "", sent: null, at: -1e9, frame: 0};
  // each frame of a drag (after the frame's pointer events moved the handle): the newest pose,
  // if viser's sender is overdue with it
  const pace = () => {
    if (drag.name === null) { drag.frame = 0; return; }
    drag.frame = requestAnimationFrame(pace);
    if (performance.now() - drag.at < __OVERDUE__) return;
    const pose = m.nodePoseData && m.nodePoseData[drag.name];
    if (!pose || !pose.position || !pose.wxyz || pose.position.join() === drag.sent) return;
    m.sendMessage({type: "TransformControlsUpdateMessage", name: drag.name,
                   wxyz: [...pose.wxyz], position: [...pose.position], owner: drag.owner});
  };
  // every message the client sends passes here (viser sets ``sendMessage`` anew on each
  // connection; the setter keeps the newest): drags' starts and ends, and poses sent
  let inner = m.sendMessage;
  const outer = (msg) => {
    if (msg && msg.type === "TransformControlsDragStartMessage") {
      drag.name = msg.name;
      drag.owner = msg.owner || "";
      drag.sent = null;
      if (!drag.frame) drag.frame = requestAnimationFrame(pace);
    } else if (msg && msg.type === "TransformControlsDragEndMessage") {
      drag.name = null;
    } else if (msg && msg.type === "TransformControlsUpdateMessage") {
      drag.sent = msg.position.join();
      drag.at = performance.now();
    }
    return inner(msg);
  };
  // the drag ends when the button goes up anywhere, whether or not viser saw it: a pause hides
  // the handle mid-drag and viser's drag-end never comes (the page then resent the handle's
  // drawn pose every frame after the pause, pulling the held keys' target back)
  const over = () => { drag.name = null; };
  window.addEventListener("pointerup", over, true);
  window.addEventListener("pointercancel", over, true);
  window.addEventListener("blur", over);
  window.addEventListener("pointermove", (ev) => { if (ev.buttons === 0) over(); }, true);
  Object.defineProperty(m, "sendMessage", {
    configurable: true,
    enumerable: true,
    get: () => (inner === null || inner === undefined ? inner : outer),
    set: (f) => { inner = f; },
  });
})();
"""

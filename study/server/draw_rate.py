"""Scene updates at the pace the page draws: the page says how fast it draws, the server sends
no faster than it can show.

The server's render loop sends the arm's poses up to ``render_hz`` (60) times a second while it
moves, and the view from above up to :data:`~study.server.inset.INSET_HZ` pictures. A page that
draws in software (a laptop without a GPU: 14 frames a second at 1366 x 768 while the arm
moves, ``benchmarks/page_fps.py``) cannot show more than it draws: each update it cannot show
still costs it a decode and an apply on the main thread it draws with, and the server its
encoding.

So the page script measures how many frames a second the page draws while it draws: three.js
renders of viser's scene in an unbroken second of frames less than :data:`IDLE_GAP_MS` apart
(viser draws on demand: a longer gap means it had nothing to draw, not that it was slow, and a
still arm's scattered redraws -- a quarter second of frames after each message, a heartbeat
each second -- never fill a second, so they say nothing). It sends the rate, rounded, when it
changed by :data:`REPORT_CHANGE` or more (a hidden text element, ``ParticipantPage.draw_hz``).
The server then sends that tab

* scene updates at most :data:`UPDATES_PER_FRAME` times that rate (each frame shows a pose at
  most half a frame old; sent at the same rate, pose and frame would beat), never below
  :data:`MIN_SCENE_HZ`, never above ``render_hz`` (:func:`scene_hz`);
* pictures from above at most once a frame, never below :data:`MIN_INSET_HZ` (:func:`inset_hz`).

A page that has not said (just loaded, or an old script) gets the full rates; one that draws
faster again (the machine's other load ended) measures the faster pace on the updates it gets
(up to twice its last report), and the rates follow it up within a few seconds. What the page
shows does not change: the newest pose at each of its frames. A page that claims a low rate
slows only its own updates; the value is parsed as hostile input
(``study.server.page_inputs.parse_draw_rate``).
"""

from __future__ import annotations

import json

from study.server import viser_door

__all__ = [
    "IDLE_GAP_MS",
    "MAX_DRAW_HZ",
    "MIN_INSET_HZ",
    "MIN_SCENE_HZ",
    "REPORT_CHANGE",
    "UPDATES_PER_FRAME",
    "Pacer",
    "draw_rate_script",
    "inset_hz",
    "scene_hz",
]

UPDATES_PER_FRAME = 2.0
"""Scene updates sent per frame the page draws."""
MIN_SCENE_HZ = 10.0
"""Scene updates a second a tab gets whatever it says."""
MIN_INSET_HZ = 5.0
"""Pictures from above a second a tab gets whatever it says."""
MAX_DRAW_HZ = 1000
"""Largest draw rate the server accepts (a value above it is refused, not clipped)."""
IDLE_GAP_MS = 500.0
"""Frames further apart than this are not a run of drawing (viser's own adaptive resolution
reads them the same way)."""
MEASURE_MS = 1000.0
"""Unbroken drawing a measurement spans."""
REPORT_CHANGE = 0.1
"""A measured rate is sent when it differs from the last one sent by this fraction or more."""


def scene_hz(draw_hz: float | None, *, render_hz: float) -> float:
    """Scene updates a second for a page that draws ``draw_hz`` frames a second:
    ``clamp(2 f, MIN_SCENE_HZ, render_hz)``; ``render_hz`` while unknown."""
    if draw_hz is None:
        return render_hz
    return min(render_hz, max(MIN_SCENE_HZ, UPDATES_PER_FRAME * draw_hz))


def inset_hz(draw_hz: float | None, *, most_hz: float) -> float:
    """Pictures from above a second: ``clamp(f, MIN_INSET_HZ, most_hz)``; ``most_hz`` while
    unknown."""
    if draw_hz is None:
        return most_hz
    return min(most_hz, max(MIN_INSET_HZ, draw_hz))


class Pacer:
    """When the next update may go, for a loop that wakes at a fixed rate but sends at a lower,
    changing one: ``due(now, hz)`` is true about ``hz`` times a second on average, each send
    moving the next due time on by ``1/hz`` (so a loop waking every 1/60 s sends 28 a second for
    ``hz=28``, not every third wake's 20), with at most half a period of credit after an idle
    stretch (no burst)."""

    def __init__(self) -> None:
        self._next = float("-inf")

    def due(self, now: float, hz: float) -> bool:
        """True (and counted as sent) if an update may go at ``now``."""
        if now < self._next:
            return False
        period = 1.0 / hz
        self._next = max(self._next, now - 0.5 * period) + period
        return True


def draw_rate_script(*, uuid: str) -> str:
    """JavaScript (installed once per page load, with the rest of the page script): measure the
    page's drawing rate and send it to the hidden element ``uuid``."""
    config = {
        "uuid": uuid,
        "gap": IDLE_GAP_MS,
        "span": MEASURE_MS,
        "change": REPORT_CHANGE,
        "most": MAX_DRAW_HZ,
    }
    return _TEMPLATE.replace("__VISER__", viser_door.CLIENT_GLOBAL).replace(
        "__CONFIG__", json.dumps(config)
    )


_TEMPLATE = r"""
(() => {
  const cfg = __CONFIG__;
  const st = window.__studyDraw = window.__studyDraw || {frames: 0, busy: 0, last: -1e9, sent: 0};
  st.uuid = cfg.uuid;
  if (st.installed) return;
  st.installed = true;
  // each render of viser's scene: an unbroken run of frames closer than cfg.gap is drawing at
  // the page's pace (a longer gap: nothing to draw, and the run starts again); after cfg.span
  // of it, the rate goes out if it changed by cfg.change or more
  const drawn = () => {
    const now = performance.now();
    const gap = now - st.last;
    st.last = now;
    if (gap > cfg.gap) { st.frames = 0; st.busy = 0; return; }
    st.frames += 1;
    st.busy += gap;
    if (st.busy < cfg.span) return;
    const hz = Math.min(cfg.most, Math.max(1, Math.round(1000 * st.frames / st.busy)));
    st.frames = 0;
    st.busy = 0;
    if (st.sent && Math.abs(hz - st.sent) < cfg.change * st.sent) return;
    const m = __VISER__;
    if (!m || !st.uuid) return;
    st.sent = hz;
    m.sendMessage({type: "GuiUpdateMessage", uuid: st.uuid, updates: {value: String(hz)}});
  };
  // the scene viser draws (it may be replaced when the viewer remounts): counted once
  const hook = () => {
    const m = __VISER__;
    const scene = m && m.scene;
    if (!scene || scene.__studyDrawn) return;
    scene.__studyDrawn = true;
    const before = scene.onAfterRender;
    scene.onAfterRender = function (...args) {
      drawn();
      if (typeof before === "function") return before.apply(this, args);
    };
  };
  hook();
  setInterval(hook, 1000);
})();
"""

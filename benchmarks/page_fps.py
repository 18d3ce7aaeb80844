"""Frames per second the participant page draws during a trial, in headless Chromium.

Debian's Chromium renders WebGL in software (SwiftShader) here, so this is a worst case: a
participant's lab machine with a GPU draws far faster. The page is joined and a trial started
as a participant would; then for ``--seconds`` each the script counts ``requestAnimationFrame``
callbacks (the browser's frame rate) while

* the arm moves: the handle's target follows a slow circle at 30 poses/s, as a drag does (with
  ``--keys``: the participant holds A, then D, half a window each);
* the participant lets go (one window right after the last pose: the arm's posture settles by
  less than a pixel, which the server does not send);
* the arm holds still: no input (the server then sends no scene updates at all).

It also counts the scene frames the server sent in each window, the pictures from above it made
(``study.server.inset``; 0 on a page without them) and the control loop's ticks, with the tick
periods' median, p99 and maximum while the arm moves. Run it on an idle machine, or side by side
with another version in the same minutes; the load average is printed with the figures::

    .venv/bin/python benchmarks/page_fps.py --seconds 5 --repeats 3

By default the measured run is the paper protocol's practice run. ``--protocol`` and ``--mode``
measure the first run of another protocol in a given mode (the experimenter skips the runs
before it), e.g. the intent display's ring::

    .venv/bin/python benchmarks/page_fps.py --protocol protocols/intent.toml --mode aggressive_shown

``--drag`` measures instead what a participant dragging the handle gets, idle and with
``--burners N`` busy loops (``benchmarks/page_drag.py``: latency from the pointer to the
server's target, the drag's duration as planned and as the server saw it, a person's pointer
against Playwright's scripted one); ``--code DIR`` serves another checkout (``git archive main
| tar -x -C DIR``) for a side-by-side run::

    .venv/bin/python benchmarks/page_fps.py --drag --burners 2 --repeats 3 --viewport 1366x768
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from playwright.sync_api import sync_playwright

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
if "--code" in sys.argv:  # serve another checkout with this script (side by side with main)
    sys.path.insert(0, os.path.abspath(sys.argv[sys.argv.index("--code") + 1]))

from benchmarks.server import feed_gizmo
from study.session import SessionStateError
from tests.browser.harness import launch, start_server
from tests.browser.page import wait_connected
from tests.browser.test_participant_flow import AGREE, join

FPS_JS = """(ms) => new Promise((done) => {
  let n = 0; const t0 = performance.now();
  const f = () => { n++; if (performance.now() - t0 < ms) requestAnimationFrame(f);
                    else done(n / ((performance.now() - t0) / 1000)); };
  requestAnimationFrame(f);
})"""


CANVAS_JS = """() => Math.max(0, ...[...document.querySelectorAll("canvas")].map(
  (c) => c.width * c.height))"""
"""The pixels of the page's largest canvas (the 3-D view) as drawn now."""


def _busy(cdp) -> dict[str, float]:
    """The page's main-thread time so far (s): all tasks, and script alone (CDP metrics)."""
    metrics = {m["name"]: m["value"] for m in cdp.send("Performance.getMetrics")["metrics"]}
    return {"task": metrics["TaskDuration"], "script": metrics["ScriptDuration"]}


BUSY: list[dict[str, float]] = []
"""Per window: the page's main thread busy (ms per s), all tasks and script alone."""


def _window(page, live, seconds: float, cdp=None) -> tuple[float, float, float, float]:
    """Over ``seconds``: frames/s drawn by the page, scene frames/s sent by the server, pictures
    from above made per second (0 where the page has none) and the control loop's ticks/s
    (with ``cdp``, the main thread's busy time is appended to ``BUSY``)."""
    before = _busy(cdp) if cdp is not None else None
    sent = live.scene_view.frames_sent
    inset = getattr(live.view, "inset", None)
    made = inset.frames if inset is not None else 0
    ticks = live.control_loop.ticks
    t = time.monotonic()
    fps = float(page.evaluate(FPS_JS, seconds * 1000))
    dt = time.monotonic() - t
    if before is not None:
        after = _busy(cdp)
        BUSY.append({k: round((after[k] - before[k]) * 1e3 / dt, 1) for k in before})
    made = (inset.frames - made) / dt if inset is not None else 0.0
    return (
        fps,
        (live.scene_view.frames_sent - sent) / dt,
        made,
        (live.control_loop.ticks - ticks) / dt,
    )


def _skip_to(srv, code: str, live, mode: str) -> None:
    """Skip runs and items, as the experimenter would, until the next run is in ``mode``."""
    while True:
        try:
            if live.session.trial_config().mode == mode:
                return
        except SessionStateError:  # a questions screen
            pass
        srv.act(code, "skip", reason="benchmark: measure a later run")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="length of each window")
    parser.add_argument("--repeats", type=int, default=3, help="windows per condition")
    parser.add_argument("--protocol", default=None, help="protocol TOML (default: the paper's)")
    parser.add_argument("--mode", default=None, help="measure the first run in this mode")
    parser.add_argument("--viewport", default="1100x720", help="page size, WxH (CSS pixels)")
    parser.add_argument(
        "--dpr",
        type=float,
        default=None,
        help="draw at this fixed pixel ratio (viser's ?fixedDpr=); default: viser's own, which"
        " drops to 0.75 while the page draws slowly, so a faster page may draw more pixels",
    )
    parser.add_argument(
        "--center",
        default="0.45,0,0.3",
        help="x,y,z (m) the handle's target circles around (0.58,0.04,0.15: near the paper "
        "scenes' box, where the robot is confident enough to show its intent)",
    )
    parser.add_argument(
        "--keys",
        action="store_true",
        help="move the arm with held keys (A, then D: sideways and back) instead of the handle",
    )
    parser.add_argument(
        "--realtime",
        type=int,
        default=None,
        help="real-time scheduling as `serve --realtime N` sets it (the browser, started"
        " first, stays ordinary; default: none)",
    )
    parser.add_argument(
        "--drag",
        action="store_true",
        help="measure drags of the handle instead (benchmarks/page_drag.py), idle and loaded",
    )
    parser.add_argument(
        "--burners", type=int, default=2, help="with --drag: busy loops for the loaded drags"
    )
    parser.add_argument("--drag-s", type=float, default=3.0, help="with --drag: a drag's length")
    parser.add_argument("--code", default=None, help="another checkout to serve (e.g. main's)")
    args = parser.parse_args()
    if args.drag:
        return _drags(args)
    with sync_playwright() as p:
        browser = launch(p)  # before the server takes its class: Chromium stays ordinary
        if args.realtime:
            from study import scheduling

            if not scheduling.set_realtime(args.realtime):
                raise SystemExit("the real-time class is not allowed here")
        return _measure(args, browser)


def _drags(args: argparse.Namespace) -> int:
    """``--drag``: the person's and the scripted drags, idle and loaded (page_drag.py)."""
    import asyncio

    from benchmarks import page_drag

    viewport = args.viewport if args.viewport != "1100x720" else "1366x768"
    result = asyncio.run(
        page_drag.measure(
            viewport=viewport, burners=args.burners, repeats=args.repeats, drag_s=args.drag_s
        )
    )
    result["code"] = args.code or "this checkout"
    print("\n".join(page_drag.summary(result)))
    print(json.dumps(result))
    return 0


def _measure(args: argparse.Namespace, browser) -> int:
    source = {} if args.protocol is None else {"source": Path(args.protocol)}
    rs = start_server(
        tempfile.mkdtemp(prefix="bench-fps-"), time_limit_s=600.0, training_runs=1, **source
    )
    srv = rs.server
    result: dict = {
        "load_average_1min": float(os.getloadavg()[0]),
        "protocol": args.protocol or "protocols/dragan2013.toml",
        "mode": args.mode,
        "realtime": args.realtime or 0,
    }
    try:
        code = srv.enrol("B01")
        srv.act(code, "start")
        live = srv.session(code)
        width, height = (int(v) for v in args.viewport.split("x"))
        result["viewport"] = args.viewport
        page = browser.new_page(viewport={"width": width, "height": height})
        page.set_default_timeout(120_000)
        cdp = page.context.new_cdp_session(page)
        cdp.send("Performance.enable")
        page.goto(rs.url if args.dpr is None else f"{rs.url}?fixedDpr={args.dpr:g}")
        wait_connected(page)
        join(page, code)
        page.get_by_role("button", name=AGREE).click()
        page.get_by_role("button", name="Start").wait_for()
        if args.mode is not None:
            _skip_to(srv, code, live, args.mode)
        page.wait_for_timeout(1000)
        page.get_by_role("button", name="Start").click()
        page.get_by_role("button", name="Close the gripper (G)").wait_for()
        page.wait_for_timeout(3000)  # the scene's first draw
        stop = threading.Event()
        center = tuple(float(v) for v in args.center.split(","))
        feeder = threading.Thread(
            target=feed_gizmo,
            args=(live, stop),
            kwargs={"center": center},
            daemon=True,
        )
        if not args.keys:
            feeder.start()
            page.wait_for_timeout(1000)
        live.control_loop._stamps.clear()  # tick periods of the moving windows only
        moving = []
        for _ in range(args.repeats):
            if args.keys:
                page.keyboard.down("a")  # sideways and back: the arm stays in its reach
                moving.append(_window(page, live, args.seconds / 2, cdp))
                page.keyboard.up("a")
                page.keyboard.down("d")
                moving.append(_window(page, live, args.seconds / 2, cdp))
                page.keyboard.up("d")
            else:
                moving.append(_window(page, live, args.seconds, cdp))
        result["main_thread_ms_per_s_moving"] = list(BUSY)
        result["canvas_px_moving"] = page.evaluate(CANVAS_JS)
        periods = live.control_loop.periods() * 1e3
        result["control_tick_period_ms_moving"] = {
            "median": round(float(np.median(periods)), 2),
            "p99": round(float(np.percentile(periods, 99)), 2),
            "max": round(float(periods.max()), 1),
        }
        cue = live.scene_view.intent
        result["ring_shown"] = cue is not None and cue.visible_goal is not None
        result["ring_updates"] = 0 if cue is None else cue.updates
        if cue is not None:  # paired windows in the same run: ring off, ring on
            pairs = []
            for _ in range(args.repeats):
                cue.suppressed = True
                off = _window(page, live, args.seconds)[0]
                cue.suppressed = False
                pairs.append((off, _window(page, live, args.seconds)[0]))
            result["ring_ab"] = {
                "fps_without": [round(a, 1) for a, _ in pairs],
                "fps_with": [round(b, 1) for _, b in pairs],
                "median_difference": round(float(np.median([b - a for a, b in pairs])), 1),
            }
            print(f"ring A/B (off, on) frames/s: {[(round(a, 1), round(b, 1)) for a, b in pairs]}")
        stop.set()
        if feeder.is_alive():
            feeder.join()
        BUSY.clear()
        let_go = [_window(page, live, args.seconds, cdp)]  # the posture settling
        result["main_thread_ms_per_s_let_go"] = list(BUSY)
        BUSY.clear()
        still = [_window(page, live, args.seconds, cdp) for _ in range(args.repeats)]
        result["main_thread_ms_per_s_still"] = list(BUSY)
        browser.close()
    finally:
        rs.stop()
    for name, rows in (("moving", moving), ("let_go", let_go), ("still", still)):
        fps = np.array([r[0] for r in rows])
        sent = np.array([r[1] for r in rows])
        above = np.array([r[2] for r in rows])
        ticks = np.array([r[3] for r in rows])
        result[name] = {
            "page_fps_median": round(float(np.median(fps)), 1),
            "page_fps_min": round(float(fps.min()), 1),
            "scene_frames_sent_per_s": round(float(np.median(sent)), 1),
            "pictures_from_above_per_s": round(float(np.median(above)), 1),
            "control_ticks_per_s": round(float(np.median(ticks)), 1),
        }
        print(
            f"arm {name}: page draws {np.median(fps):.1f} frames/s (min {fps.min():.1f},"
            f" {len(fps)} x {args.seconds / (2 if args.keys and name == 'moving' else 1):g} s);"
            f" server sends {np.median(sent):.1f} scene frames/s"
            f" and {np.median(above):.1f} pictures from above/s; control {np.median(ticks):.1f}"
            " ticks/s"
        )
    print(f"control tick periods while moving (ms): {result['control_tick_period_ms_moving']}")
    print(f"3-D view drawn at {result['canvas_px_moving']} pixels while moving")
    print(
        "page main thread busy (ms/s; all tasks, script): moving"
        f" {result['main_thread_ms_per_s_moving']}, still {result['main_thread_ms_per_s_still']}"
    )
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())

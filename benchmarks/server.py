"""Study server under load: scene update rate, control rate, input-to-command latency.

One headless Chromium (Debian's) is connected to the participant view of a running trial
(the paper's protocol, 100 Hz control). Measured:

* update_hz: scene pose updates per second the browser's websocket receives (frames that carry
  a batched-mesh pose update), median over 1 s windows (target >= 55 Hz);
* control_hz: ticks per second of the session's control loop (target within 2 % of the
  protocol's rate), and the p99 of its tick periods;
* input_to_command_ms: time from a gizmo pose arriving at the server (``set_target``, the
  call the gizmo callback makes) to the control tick whose command uses it (target: median
  at most one control period); poses arrive at 30 Hz at random phases, like a drag;
* then three more sessions are started (four trials on one server, each with its own
  simulation and control thread) and each session's control rate is measured again.

Usage: ``.venv/bin/python benchmarks/server.py [--seconds 10]``. Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from playwright.sync_api import sync_playwright  # noqa: E402

from tests.browser.harness import FrameLog, decode_frame, launch, start_server  # noqa: E402


def _pose_update(message: dict) -> bool:
    updates = message.get("updates")
    return isinstance(updates, dict) and "batched_positions" in updates


def update_rate(frames: list[tuple[float, bytes]], t0: float, t1: float) -> tuple[float, int]:
    """Median over 1 s windows of pose-carrying frames per second in [t0, t1]."""
    stamps = [
        t
        for t, payload in frames
        if t0 <= t <= t1 and any(map(_pose_update, decode_frame(payload)))
    ]
    if not stamps:
        return 0.0, 0
    edges = np.arange(t0, t1 - 1.0 + 1e-9, 1.0)
    counts = [sum(1 for t in stamps if e <= t < e + 1.0) for e in edges]
    return float(np.median(counts)), len(stamps)


def feed_gizmo(live, stop: threading.Event, *, rate_hz: float = 30.0) -> None:
    """Gizmo poses at ``rate_hz`` with random phase, moving slowly inside the reach."""
    rng = random.Random(1)
    k = 0
    while not stop.is_set():
        k += 1
        target = np.array([0.45 + 0.05 * np.sin(k / 30), 0.05 * np.cos(k / 40), 0.3])
        live._on_target(target)
        time.sleep(rng.uniform(0.5, 1.5) / rate_hz)


def start_trial(live, page=None) -> None:
    if live.session.phase() == "consent":
        live.session.agree()
    if page is not None:
        page.get_by_role("button", name="Start").click(timeout=120_000)
    else:
        live._start_trial()
    deadline = time.monotonic() + 60
    while live.control_loop is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if live.control_loop is None:
        raise RuntimeError("the trial did not start")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measurement window")
    args = parser.parse_args()

    tmp = tempfile.mkdtemp(prefix="bench-server-")
    rs = start_server(tmp, time_limit_s=600.0, training_runs=1)
    srv = rs.server
    result: dict = {}
    try:
        code = srv.enrol("B01")
        srv.act(code, "start")
        live = srv.session(code)
        live.session.agree()
        with sync_playwright() as p:
            browser = launch(p)
            page = browser.new_page(viewport={"width": 1000, "height": 700})
            page.set_default_timeout(120_000)
            log = FrameLog().attach(page)
            page.goto(rs.url)
            page.get_by_text("Connected").first.wait_for()
            page.get_by_role("button", name="Start").wait_for()
            page.screenshot()  # waits for the first (slow, software WebGL) draw of the scene
            start_trial(live, page)
            rate = live.control_loop.rate_hz
            page.wait_for_timeout(
                2000
            )  # settle (sync Playwright delivers events only in its calls)

            stop = threading.Event()
            feeder = threading.Thread(target=feed_gizmo, args=(live, stop), daemon=True)
            live.participant_input.latencies_s.clear()
            feeder.start()
            t0 = time.monotonic()
            ticks0 = live.control_loop.ticks
            sent0 = live.scene_view.frames_sent
            page.wait_for_timeout(args.seconds * 1000)
            t1 = time.monotonic()
            ticks1 = live.control_loop.ticks
            sent_hz = (live.scene_view.frames_sent - sent0) / (t1 - t0)
            stop.set()
            feeder.join()
            periods = live.control_loop.periods()
            lat = np.array(live.participant_input.latencies_s) * 1e3
            with log.lock:
                frames = list(log.frames)
            update_hz, n_updates = update_rate(frames, t0, t1)
            control_hz = (ticks1 - ticks0) / (t1 - t0)
            result.update(
                update_hz=round(update_hz, 1),
                update_frames=n_updates,
                server_render_hz=round(sent_hz, 1),
                render_ms_median=round(float(np.median(live.scene_view.render_s)) * 1e3, 3),
                render_ms_p99=round(float(np.percentile(live.scene_view.render_s, 99)) * 1e3, 3),
                control_hz=round(control_hz, 2),
                control_setting_hz=rate,
                control_error_pct=round(100 * abs(control_hz - rate) / rate, 2),
                control_period_ms_median=round(float(np.median(periods)) * 1e3, 3),
                control_period_ms_p99=round(float(np.percentile(periods, 99)) * 1e3, 3),
                overruns=live.control_loop.overruns,
                input_to_command_ms={
                    "median": round(float(np.median(lat)), 3),
                    "p99": round(float(np.percentile(lat, 99)), 3),
                    "n": len(lat),
                },
            )
            print(
                f"1 session + browser: scene updates {update_hz:.1f} Hz ({n_updates} frames),"
                f" control {control_hz:.2f} Hz (setting {rate}),"
                f" input->command median {np.median(lat):.2f} ms p99 {np.percentile(lat, 99):.2f} ms"
            )

            # Four sessions on one server.
            others = []
            for k in range(3):
                c = srv.enrol(f"B0{k + 2}")
                srv.act(c, "start")
                others.append(srv.session(c))
            for other in others:
                start_trial(other)
            page.wait_for_timeout(2000)
            lives = [live, *others]
            marks = [(s.control_loop.ticks, time.monotonic()) for s in lives]
            page.wait_for_timeout(args.seconds * 1000)
            rates = [
                (s.control_loop.ticks - n) / (time.monotonic() - t)
                for s, (n, t) in zip(lives, marks, strict=True)
            ]
            t2 = time.monotonic()
            with log.lock:
                frames = list(log.frames)
            update4_hz, _ = update_rate(frames, t2 - args.seconds, t2)
            result.update(
                sessions=4,
                sessions_control_hz=[round(r, 2) for r in rates],
                sessions_control_error_pct_max=round(
                    max(100 * abs(r - rate) / rate for r in rates), 2
                ),
                sessions_update_hz=round(update4_hz, 1),
            )
            print(
                f"4 sessions: control {', '.join(f'{r:.2f}' for r in rates)} Hz;"
                f" scene updates to the browser {update4_hz:.1f} Hz"
            )
            browser.close()
    finally:
        rs.stop()
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())

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
  simulation and control thread, each fed gizmo poses at 30 Hz) and each session's control
  rate is measured again, with the gaps between consecutive sample commits of every session
  (``batch_gap_ms``: max, p99, median and how many exceed 250 ms; the promise is that samples
  reach the store at most 250 ms apart, so the maximum is the figure that matters).

``--no-browser`` skips the browser (and the single-session figures that need it) and measures
the four sessions alone, which separates the server's own load from Chromium's software WebGL.
``--sessions N`` measures N sessions alone the same way; ``--find`` starts at ``--sessions``
and adds 2 (a fresh server each time) until the sessions no longer hold (each within 2 % of
100 Hz and sample commits at most 250 ms apart), and prints the largest number that held.

``--scenario storm`` and ``--scenario tabs`` measure the participant port's promise instead:
the control loop holds >= 95 Hz in every 0.25-s window and sample commits stay <= 250 ms apart

* ``storm``: one session with a Chromium tab attached, while another process runs a
  reconnect storm (``tests/attacker.py storm``: 32 tasks from 8 loopback addresses opening a
  websocket, sending a camera message and closing, in a loop);
* ``tabs``: four sessions, each with its own Chromium tab attached (one browser, four pages);

each reports, per session, the worst 0.25-s window of its control loop (ticks a second), how
many windows fell under 95, the sample-commit gaps, the garbage collector's longest pauses in
the window, whether the session ever paused, and the load average before and after.
``--code DIR`` runs the same measurement against another checkout (``git archive main``),
side by side; ``--priority N`` gives the server the nice value ``serve --priority`` would
(``serve``'s default is -10; the benchmark's is none) and ``--realtime N`` the real-time scheduling
``serve --realtime N`` would (``serve``'s default is 10; the benchmark's none).

Usage: ``.venv/bin/python benchmarks/server.py [--seconds 10] [--no-browser]
[--scenario storm|tabs] [--code DIR]``. Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import gc
import itertools
import json
import multiprocessing
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
if "--code" in sys.argv:  # measure another checkout with this script (side by side with main)
    sys.path.insert(0, str(Path(sys.argv[sys.argv.index("--code") + 1]).resolve()))

from playwright.sync_api import sync_playwright  # noqa: E402

from tests.browser.harness import FrameLog, decode_frame, launch, start_server  # noqa: E402
from tests.browser.test_participant_flow import join  # noqa: E402


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


def feed_gizmo(
    live, stop: threading.Event, *, rate_hz: float = 30.0, center=(0.45, 0.0, 0.3)
) -> None:
    """Gizmo poses at ``rate_hz`` with random phase, moving slowly inside the reach on a 5 cm
    loop around ``center``."""
    rng = random.Random(1)
    k = 0
    cx, cy, cz = center
    while not stop.is_set():
        k += 1
        target = np.array([cx + 0.05 * np.sin(k / 30), cy + 0.05 * np.cos(k / 40), cz])
        live.input.on_target(target)
        time.sleep(rng.uniform(0.5, 1.5) / rate_hz)


def batch_gaps(lives, t0: float, t1: float) -> dict:
    """Gaps between consecutive sample commits of each session in [t0, t1], pooled (ms), and
    the first and last commit's distance from the window's edges (a stalled writer shows)."""
    gaps: list[float] = []
    for live in lives:
        stamps = [t for t in live.session.sample_stats.committed_at if t0 <= t <= t1]
        if not stamps:
            gaps.append((t1 - t0) * 1e3)
            continue
        points = [t0, *stamps, t1]
        gaps += [(b - a) * 1e3 for a, b in itertools.pairwise(points)]
    g = np.array(gaps)
    return {
        "max": round(float(g.max()), 1),
        "p99": round(float(np.percentile(g, 99)), 1),
        "median": round(float(np.median(g)), 1),
        "over_250": int((g > 250).sum()),
        "n": len(g),
    }


def start_trial(live, page=None) -> None:
    if live.session.phase() == "consent":
        live.session.agree()
    if page is not None:
        page.get_by_role("button", name="Start").click(timeout=120_000)
    else:
        live.start_trial()
    deadline = time.monotonic() + 60
    while live.control_loop is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if live.control_loop is None:
        raise RuntimeError("the trial did not start")


def many_sessions(srv, running: list, *, n: int = 4, seconds: float, wait) -> dict:
    """Start sessions until ``n`` run trials at once, feed each gizmo poses, and measure their
    control rates and sample-commit gaps over ``seconds``; ``wait(s)`` sleeps (through
    Playwright when a browser is attached, so its events keep flowing). ``holds``: every
    session within 2 % of its rate and no sample commit more than 250 ms after the last."""
    others = []
    for k in range(n - len(running)):
        c = srv.enrol(f"B{k + 2 + len(running):02d}")
        srv.act(c, "start")
        others.append(srv.session(c))
    for other in others:
        start_trial(other)
    lives = [*running, *others]
    stop = threading.Event()
    feeders = [threading.Thread(target=feed_gizmo, args=(s, stop), daemon=True) for s in lives]
    for f in feeders:
        f.start()
    wait(2.0)
    rate = lives[0].control_loop.rate_hz
    marks = [(s.control_loop.ticks, time.monotonic()) for s in lives]
    t0 = time.monotonic()
    wait(seconds)
    t1 = time.monotonic()
    rates = [(s.control_loop.ticks - n) / (t1 - t) for s, (n, t) in zip(lives, marks, strict=True)]
    stop.set()
    for f in feeders:
        f.join()
    gaps = batch_gaps(lives, t0, t1)
    commit_ms = np.array([c for s in lives for c in s.session.sample_stats.commit_s]) * 1e3
    error_pct = max(100 * abs(r - rate) / rate for r in rates)
    print(
        f"{n} sessions: control {', '.join(f'{r:.2f}' for r in rates)} Hz;"
        f" sample batches max gap {gaps['max']:.0f} ms, p99 {gaps['p99']:.0f} ms,"
        f" median {gaps['median']:.0f} ms, {gaps['over_250']} of {gaps['n']} over 250 ms;"
        f" commit median {np.median(commit_ms):.1f} ms, max {commit_ms.max():.1f} ms"
    )
    return {
        "sessions": n,
        "holds": bool(error_pct <= 2.0 and gaps["max"] <= 250.0),
        "sessions_control_hz": [round(r, 2) for r in rates],
        "sessions_control_error_pct_max": round(error_pct, 2),
        "batch_gap_ms": gaps,
        "commit_ms": {
            "median": round(float(np.median(commit_ms)), 2),
            "p99": round(float(np.percentile(commit_ms, 99)), 2),
            "max": round(float(commit_ms.max()), 2),
        },
    }


class GcPauses:
    """The garbage collector's pauses (start time, seconds, generation) in this process."""

    def __init__(self) -> None:
        self.pauses: list[tuple[float, float, int]] = []
        self._start = 0.0
        gc.callbacks.append(self._callback)

    def _callback(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._start = time.monotonic()
        else:
            now = time.monotonic()
            self.pauses.append((self._start, now - self._start, int(info["generation"])))

    def worst(self, t0: float, t1: float, n: int = 3) -> list[list[float]]:
        """The ``n`` longest pauses that started in [t0, t1]: [ms, generation]."""
        inside = sorted((p for p in self.pauses if t0 <= p[0] <= t1), key=lambda p: -p[1])
        return [[round(d * 1e3, 1), g] for _, d, g in inside[:n]]


def loop_windows(stamps_seen: list[float], t0: float, t1: float, *, width: float = 0.25) -> dict:
    """Ticks a second of a loop (its tick stamps, copied at ``t1``) in consecutive ``width``-s
    windows of [t0, t1]: the worst window and how many fell under 95. The loop keeps only its
    last 2,048 stamps (20.5 s at 100 Hz): a copy taken later than ``t1`` would have lost the
    window's first ticks and shown them as a stall, so a copy that does not reach back to ``t0``
    is refused."""
    if not stamps_seen or stamps_seen[0] > t0 + width:
        raise RuntimeError("the loop's stamps do not reach back to the window's start")
    stamps = np.array([t for t in stamps_seen if t0 <= t <= t1])
    edges = np.arange(t0, t1 - width + 1e-9, width)
    rates = np.array([((stamps >= e) & (stamps < e + width)).sum() for e in edges]) / width
    return {
        "worst_hz": float(rates.min()),
        "under_95": int((rates < 95).sum()),
        "windows": len(rates),
    }


def _drive_tabs(conn) -> None:
    """In a child process: one Chromium; once the parent sends (url, join codes), a tab per
    code that joins and presses Start, each reported back; then the pages keep drawing until
    the parent says stop. Playwright runs here and not in the server's process because its
    client decodes every websocket frame its tabs receive (a third of the server process's
    GIL time with four tabs, by py-spy), which no participant's browser costs a server."""
    with sync_playwright() as p:
        browser = launch(p)
        url, codes = conn.recv()
        pages = []
        for code in codes:
            page = browser.new_page(viewport={"width": 1000, "height": 700})
            page.set_default_timeout(120_000)
            page.goto(url)
            join(page, code, then="Start")
            page.get_by_role("button", name="Start").click()  # the trial's own Start
            pages.append(page)
            conn.send(code)
        while not conn.poll():
            pages[0].wait_for_timeout(200)
        browser.close()


def _ordinary() -> None:
    """In a child before it runs: an ordinary process (this one may hold the server's)."""
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    os.setpriority(os.PRIO_PROCESS, 0, 0)


def _wait_for_trial(live, *, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while live.control_loop is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if live.control_loop is None:
        raise RuntimeError("the trial did not start")


def port_scenario(args: argparse.Namespace) -> dict:
    """``--scenario storm`` or ``tabs`` (see module docstring). The tabs' browser is a child
    process started first, so it keeps the default priority (a participant's own machine);
    then (with ``--priority``) this thread takes the server's priority as ``serve`` does and
    the server starts, so its threads inherit it."""
    n_tabs = 1 if args.scenario == "storm" else 4
    pauses = GcPauses()
    result: dict = {"scenario": args.scenario, "code": args.code or str(ROOT)}
    here, there = multiprocessing.get_context("spawn").Pipe()
    driver = multiprocessing.get_context("spawn").Process(target=_drive_tabs, args=(there,))
    driver.start()
    if args.priority is not None:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), args.priority)
    if args.switch_ms is not None:
        sys.setswitchinterval(args.switch_ms / 1000)
    result["switch_ms"] = round(sys.getswitchinterval() * 1000, 3)
    result["priority"] = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    if args.realtime:
        from study import scheduling

        if not scheduling.set_realtime(args.realtime):
            raise SystemExit("the real-time class is not allowed here")
    result["realtime"] = args.realtime or 0
    rs = start_server(tempfile.mkdtemp(prefix="bench-port-"), time_limit_s=600.0, training_runs=1)
    srv = rs.server
    stop = threading.Event()
    attacker = None
    try:
        lives = []
        for k in range(n_tabs):
            code = srv.enrol(f"B0{k + 1}")
            srv.act(code, "start")
            lives.append(srv.session(code))
            lives[-1].session.agree()
        here.send((rs.url, [live.code for live in lives]))
        for live in lives:
            if not here.poll(180):
                raise RuntimeError("the browser did not open its tabs")
            here.recv()
            _wait_for_trial(live)
        feeders = [
            threading.Thread(target=feed_gizmo, args=(live, stop), daemon=True) for live in lives
        ]
        for f in feeders:
            f.start()
        time.sleep(3.0)  # the first draws of the scenes
        if args.scenario == "storm" and args.attack != "none":
            port, seconds = str(srv.participant_port), str(args.seconds + 2)
            argv = ["tests.attacker", args.attack, "--port", port, "--seconds", seconds]
            attacker = subprocess.Popen(
                [sys.executable, "-m", *argv, "--addresses", "8", "--tasks", "32"],
                cwd=ROOT,
                stdout=subprocess.PIPE,
                text=True,
                preexec_fn=_ordinary,  # not the server's priority: another program
            )
            time.sleep(1.5)
        result["load_before"] = [round(x, 2) for x in os.getloadavg()]
        t0 = time.monotonic()
        time.sleep(args.seconds)
        t1 = time.monotonic()
        stamps_seen = [list(live.control_loop._stamps) for live in lives]
        result["load_after"] = [round(x, 2) for x in os.getloadavg()]
        stop.set()
        if attacker is not None:
            out, _ = attacker.communicate(timeout=60)
            result["attacker"] = json.loads(out.strip().splitlines()[-1])
        result["sessions"] = [
            {
                **loop_windows(seen, t0, t1),
                "batch_gap_ms": batch_gaps([live], t0, t1),
                "paused": bool(live.session.paused),
            }
            for live, seen in zip(lives, stamps_seen, strict=True)
        ]
        result["gc_worst_ms"] = pauses.worst(t0, t1)
    finally:
        stop.set()
        if attacker is not None and attacker.poll() is None:
            attacker.kill()
        here.send("stop")
        driver.join(60)
        if driver.is_alive():
            driver.kill()
        rs.stop()
    worst = min(s["worst_hz"] for s in result["sessions"])
    gap = max(s["batch_gap_ms"]["max"] for s in result["sessions"])
    print(
        f"{args.scenario}: worst 0.25-s window {worst:.0f} Hz, largest commit gap {gap:.0f} ms,"
        f" load {result['load_before']} -> {result['load_after']}"
    )
    return result


def sessions_alone(n: int, *, seconds: float) -> dict:
    """``n`` sessions on one fresh server, no browser (:func:`many_sessions`)."""
    rs = start_server(tempfile.mkdtemp(prefix="bench-server-"), time_limit_s=600.0, training_runs=1)
    try:
        return many_sessions(rs.server, [], n=n, seconds=seconds, wait=time.sleep)
    finally:
        rs.stop()


def find_sessions(args: argparse.Namespace) -> dict:
    """From ``--sessions`` up by 2, a fresh server each time, until one does not hold; the
    largest number that held, and every run's figures."""
    runs = []
    n = args.sessions
    while True:
        run = sessions_alone(n, seconds=args.seconds)
        runs.append(run)
        if not run["holds"] or n >= 64:
            break
        n += 2
    held = [r["sessions"] for r in runs if r["holds"]]
    largest = max(held, default=0)
    print(f"largest number of sessions that held: {largest} ({os.cpu_count()} CPUs)")
    return {"largest_holding": largest, "cpus": os.cpu_count(), "runs": runs}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measurement window")
    parser.add_argument("--no-browser", action="store_true", help="sessions without a browser only")
    parser.add_argument(
        "--sessions",
        type=int,
        default=4,
        help="sessions at once (default 4; implies --no-browser unless 4)",
    )
    parser.add_argument(
        "--find",
        action="store_true",
        help="without a browser: from --sessions up by 2, the largest number that holds",
    )
    parser.add_argument("--scenario", choices=("storm", "tabs"), help="the port's promise")
    parser.add_argument("--code", help="another checkout to measure (e.g. main's)")
    parser.add_argument(
        "--priority",
        type=int,
        default=None,
        help="the server's nice value, set as `serve --priority` does (default: unchanged)",
    )
    parser.add_argument(
        "--realtime",
        type=int,
        default=None,
        help="real-time scheduling as `serve --realtime N` sets it: the control loops at N,"
        " the rest of the server at 1 (default: none, ordinary threads)",
    )
    parser.add_argument(
        "--switch-ms",
        type=float,
        default=None,
        help="the interpreter's thread switch interval, ms (Python's default is 5)",
    )
    parser.add_argument(
        "--attack", default="storm", help="storm scenario: the attack (tests/attacker.py kinds)"
    )
    args = parser.parse_args()
    if args.scenario is not None:
        print(json.dumps(port_scenario(args)))
        return 0

    if args.realtime and (args.find or args.no_browser or args.sessions != 4):
        from study import scheduling  # no browser to keep ordinary

        if not scheduling.set_realtime(args.realtime):
            raise SystemExit("the real-time class is not allowed here")
    if args.find:
        print(json.dumps(find_sessions(args)))
        return 0
    if args.no_browser or args.sessions != 4:
        print(json.dumps(sessions_alone(args.sessions, seconds=args.seconds)))
        return 0
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
            join(page, code, then="Start")  # a participant tab always types the join code
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

            result.update(
                many_sessions(
                    srv, [live], seconds=args.seconds, wait=lambda s: page.wait_for_timeout(s * 1e3)
                )
            )
            with log.lock:
                frames = list(log.frames)
            t2 = time.monotonic()
            update4_hz, _ = update_rate(frames, t2 - args.seconds, t2)
            result.update(sessions_update_hz=round(update4_hz, 1))
            print(f"4 sessions: scene updates to the browser {update4_hz:.1f} Hz")
            browser.close()
    finally:
        rs.stop()
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())

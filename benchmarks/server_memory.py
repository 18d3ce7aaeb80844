"""Study server memory over time: does a long session plateau, and how long are GC pauses?

A study server runs ``--sessions`` live sessions (default 2), each in a trial fed gizmo poses at
30 Hz (``benchmarks/server.py``'s ``feed_gizmo``); ``--browser`` attaches a headless Chromium tab
to the first session. Every ``--every`` seconds one line: the process's resident memory (RSS,
MB), the objects the cyclic collector tracks (``gc.get_objects()``: what a full collection
walks; frozen start-up objects are not among them), the longest generation-2 pause and the
control loops' worst 0.25-s window in that interval. At the end:

* ``rss_slope_mb_s``: least-squares slope of RSS over the second half of the run (the first
  half holds start-up, the tab's first scene and the allocator's warm-up), and over all of it;
* ``objects_slope_per_s``: the same for tracked objects, and the types that grew most
  between the first and last sample;
* ``gc2_ms``: generation-2 pauses (count, max, p99, median), the loops' worst window and how
  many 0.25-s windows fell under 95 Hz (the sampling itself, a list of the tracked objects,
  takes a few ms);
* with ``--tracemalloc N``: the top allocation sites (N frames) grown between the first and
  the last sample (tracemalloc slows the server: its rates are then not the served ones).

``--attack KIND`` runs ``tests/attacker.py KIND`` (e.g. ``storm``) against the participant port
meanwhile (its connections leave garbage: collections come often). ``--time-limit`` is the
trials' time limit (default 600 s, longer than the run: one trial runs all the way, as in the
attack pass); ``--code DIR`` measures another checkout (``git archive main | tar -x -C DIR``)
with this script, side by side. The load average before and after is printed: the worst
windows follow the machine's load more than anything in the server.

Usage: ``.venv/bin/python benchmarks/server_memory.py [--seconds 180] [--sessions 2]
[--browser] [--attack storm] [--tracemalloc 8] [--code DIR]``. Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import collections
import gc
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
if "--code" in sys.argv:  # measure another checkout with this script (side by side with main)
    sys.path.insert(0, str(Path(sys.argv[sys.argv.index("--code") + 1]).resolve()))

from benchmarks.server import GcPauses, feed_gizmo, loop_windows, start_trial  # noqa: E402
from tests.browser.harness import launch, start_server  # noqa: E402


def rss_mb() -> float:
    """This process's resident set size, MB (Linux ``/proc/self/status``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def type_counts() -> collections.Counter[str]:
    """Objects the collector tracks (outside the frozen generation), by type name."""
    return collections.Counter(type(o).__name__ for o in gc.get_objects())


def slope(t: list[float], y: list[float]) -> float:
    """Least-squares slope of ``y`` over ``t`` (per second); 0 with fewer than 2 points."""
    return float(np.polyfit(t, y, 1)[0]) if len(t) >= 2 else 0.0


def pause_stats(pauses: GcPauses, t0: float, t1: float) -> dict:
    """Generation-2 pauses that started in [t0, t1], ms."""
    d = np.array([p[1] for p in pauses.pauses if p[2] == 2 and t0 <= p[0] <= t1]) * 1e3
    if d.size == 0:
        return {"n": 0, "max": 0.0, "p99": 0.0, "median": 0.0}
    return {
        "n": int(d.size),
        "max": round(float(d.max()), 1),
        "p99": round(float(np.percentile(d, 99)), 1),
        "median": round(float(np.median(d)), 1),
    }


class Sampler:
    """One row per interval: elapsed s, RSS MB, tracked objects, gen-2 max ms, worst Hz."""

    def __init__(self, lives: list, pauses: GcPauses, *, trace: bool) -> None:
        self.lives = lives
        self.pauses = pauses
        self.trace = trace
        self.rows: list[dict] = []
        self.t0 = time.monotonic()
        self.first_types = type_counts()
        self.first_snapshot = tracemalloc.take_snapshot() if trace else None
        self._last = self.t0
        self.windows: list[dict] = []

    def sample(self) -> dict:
        now = time.monotonic()
        windows = [loop_windows(list(s.control_loop._stamps), self._last, now) for s in self.lives]
        self.windows += windows
        row = {
            "t": round(now - self.t0, 1),
            "rss_mb": round(rss_mb(), 1),
            "objects": len(gc.get_objects()),
            "gc2_max_ms": pause_stats(self.pauses, self._last, now)["max"],
            "worst_hz": min(w["worst_hz"] for w in windows),
        }
        self.rows.append(row)
        self._last = now
        print(
            f"{row['t']:7.1f} s  RSS {row['rss_mb']:7.1f} MB  objects {row['objects']:8d}"
            f"  gc2 max {row['gc2_max_ms']:6.1f} ms  worst window {row['worst_hz']:.0f} Hz",
            flush=True,
        )
        return row

    def summary(self, *, frames: int) -> dict:
        t = [r["t"] for r in self.rows]
        half = [i for i, x in enumerate(t) if x >= t[-1] / 2]
        rss = [r["rss_mb"] for r in self.rows]
        objs = [r["objects"] for r in self.rows]
        grown = (type_counts() - self.first_types).most_common(8)
        out = {
            "rss_mb": {"first": rss[0], "last": rss[-1], "max": max(rss)},
            "rss_slope_mb_s": {
                "all": round(slope(t, rss), 4),
                "second_half": round(slope([t[i] for i in half], [rss[i] for i in half]), 4),
            },
            "objects": {"first": objs[0], "last": objs[-1]},
            "objects_slope_per_s": {
                "all": round(slope(t, objs), 1),
                "second_half": round(slope([t[i] for i in half], [objs[i] for i in half]), 1),
            },
            "types_grown": grown,
            "gc2_ms": pause_stats(self.pauses, self.t0, time.monotonic()),
            "worst_hz": min(w["worst_hz"] for w in self.windows),
            "windows_under_95": sum(w["under_95"] for w in self.windows),
            "windows": sum(w["windows"] for w in self.windows),
        }
        if self.first_snapshot is not None:
            diff = tracemalloc.take_snapshot().compare_to(self.first_snapshot, "traceback")
            out["tracemalloc_top"] = [
                {
                    "kb": round(d.size_diff / 1024, 1),
                    "count": d.count_diff,
                    "where": [f"{f.filename.split('/')[-1]}:{f.lineno}" for f in d.traceback][
                        -frames:
                    ],
                }
                for d in diff[:10]
            ]
        return out


def start_sessions(rs, n: int, browser) -> tuple[list, object]:
    """``n`` live sessions, each in its first trial; with ``browser``, the first one's tab
    (returned, else ``None``) types its code and presses Start."""
    srv = rs.server
    lives = []
    for k in range(n):
        code = srv.enrol(f"M{k + 1:02d}")
        srv.act(code, "start")
        lives.append(srv.session(code))
    page = None
    for k, live in enumerate(lives):
        live.session.agree()
        if k == 0 and browser is not None:
            from tests.browser.test_participant_flow import join

            page = browser.new_page(viewport={"width": 1000, "height": 700})
            page.set_default_timeout(120_000)
            page.goto(rs.url)
            join(page, live.code, then="Start")
            start_trial(live, page)
        else:
            start_trial(live)
    return lives, page


def measure(args: argparse.Namespace, rs, lives: list, page, pauses: GcPauses) -> dict:
    """Sample every ``--every`` s for ``--seconds`` (an attacker meanwhile with ``--attack``);
    waits through Playwright when a tab is attached, so its events keep flowing."""

    def wait(seconds: float) -> None:
        if page is not None:
            page.wait_for_timeout(seconds * 1000)
        else:
            time.sleep(seconds)

    attacker = None
    if args.attack:
        argv = ["--port", str(rs.server.participant_port), "--seconds", str(args.seconds + 5)]
        attacker = subprocess.Popen(
            [sys.executable, "-m", "tests.attacker", args.attack, *argv],
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
        )
    try:
        wait(2.0)
        load_before = [round(x, 2) for x in os.getloadavg()]
        sampler = Sampler(lives, pauses, trace=bool(args.tracemalloc))
        end = sampler.t0 + args.seconds
        while time.monotonic() < end - 1e-3:
            wait(min(args.every, end - time.monotonic()))
            sampler.sample()
    finally:
        if attacker is not None:
            attacker.kill()
            attacker.wait()
    return {
        "code": args.code or str(ROOT),
        "attack": args.attack,
        "sessions": args.sessions,
        "browser": bool(args.browser),
        "seconds": args.seconds,
        "paused": [bool(s.session.paused) for s in lives],
        "load": [load_before, [round(x, 2) for x in os.getloadavg()]],
        **sampler.summary(frames=args.tracemalloc or 1),
        "rows": sampler.rows,
    }


def run(args: argparse.Namespace) -> dict:
    if args.tracemalloc:
        tracemalloc.start(args.tracemalloc)
    pauses = GcPauses()
    playwright = browser = None
    if args.browser:
        from playwright.sync_api import sync_playwright

        playwright = sync_playwright().start()
        browser = launch(playwright)
    rs = start_server(
        tempfile.mkdtemp(prefix="bench-memory-"), time_limit_s=args.time_limit, training_runs=1
    )
    stop = threading.Event()
    try:
        lives, page = start_sessions(rs, args.sessions, browser)
        for live in lives:
            threading.Thread(target=feed_gizmo, args=(live, stop), daemon=True).start()
        s = measure(args, rs, lives, page, pauses)
    finally:
        stop.set()
        rs.stop()
        if browser is not None:
            browser.close()
            playwright.stop()
    print(
        f"RSS {s['rss_mb']['first']} -> {s['rss_mb']['last']} MB"
        f" (slope {s['rss_slope_mb_s']['all']} MB/s, second half"
        f" {s['rss_slope_mb_s']['second_half']} MB/s); objects {s['objects']['first']} ->"
        f" {s['objects']['last']}; gen-2 GC {s['gc2_ms']}; worst window {s['worst_hz']:.0f} Hz,"
        f" {s['windows_under_95']} of {s['windows']} under 95; load {s['load']}"
    )
    return s


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=180.0, help="measurement length")
    parser.add_argument("--every", type=float, default=10.0, help="seconds between samples")
    parser.add_argument("--sessions", type=int, default=2, help="live sessions in trials")
    parser.add_argument("--browser", action="store_true", help="a Chromium tab on the first")
    parser.add_argument("--time-limit", type=float, default=600.0, help="the trials' limit, s")
    parser.add_argument(
        "--tracemalloc", type=int, default=0, help="trace allocations with N frames (slow)"
    )
    parser.add_argument(
        "--attack", help="run tests/attacker.py KIND (e.g. storm) against the port meanwhile"
    )
    parser.add_argument("--code", help="another checkout to measure (e.g. main's)")
    args = parser.parse_args()
    print(json.dumps(run(args)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

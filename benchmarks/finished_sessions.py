"""Threads and memory of a study server that serves many short sessions to their end.

A study server (``tests.browser.harness.start_server``) serves ``--sessions`` participants one
after the other, each to a completed session: enrolled, started, consented, every step skipped by
the experimenter, the debrief finished. With ``--tabs`` each has a tab (a raw websocket client,
``tests.support.raw_client``; the port's gate on new tabs per address and the throttle on
typed codes are off, as in ``tests/test_port_hostile_clients.py``) that joins with the code, consents, waits for the end screen and
leaves, as an online participant's tab does. Every ``--every`` sessions one line: the sessions
served, the process's threads, the sessions in the server's registry, resident memory (RSS, MB)
and the objects the collector tracks. At the end it waits ``--grace`` seconds plus a sweep, when
the server has one (``finished_grace_s``; the same seconds are passed to it), and prints the last
line and one JSON object.

``--code DIR`` measures another checkout with this script (``git archive main | tar -x -C
DIR``), side by side: there a finished session may stay for the life of the process.

Usage: ``.venv/bin/python benchmarks/finished_sessions.py [--sessions 100] [--every 10] [--tabs]
[--grace 1] [--code DIR]``.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import inspect
import json
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
if "--code" in sys.argv:  # measure another checkout with this script (side by side with main)
    sys.path.insert(0, str(Path(sys.argv[sys.argv.index("--code") + 1]).resolve()))

from study.server.firewall import Firewall, FirewallConfig  # noqa: E402
from study.server.join import JoinThrottle  # noqa: E402
from study.server.server import StudyServer  # noqa: E402
from tests.browser.harness import run_async, start_server, wait_until  # noqa: E402
from tests.support.raw_client import AGREE, RawClient  # noqa: E402

END_TEXT = "You may close this page now."


def rss_mb() -> float:
    """This process's resident set size, MB (Linux ``/proc/self/status``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def skip_to_end(srv, code: str) -> None:  # type: ignore[no-untyped-def]
    """The experimenter skips every step after consent; the participant finishes."""
    live = srv.session(code)
    while live.session.phase() not in ("debrief", "done"):
        srv.act(code, "skip", reason="benchmark: served to its end")
    live.finish()


def serve_one(srv, participant: str, *, tab: bool) -> None:  # type: ignore[no-untyped-def]
    """One participant's whole session (see module docstring)."""
    code = srv.enrol(participant)
    srv.act(code, "start")
    if not tab:
        srv.session(code).session.agree()
        skip_to_end(srv, code)
        return

    async def visit() -> None:
        async with RawClient(srv.participant_port) as c:
            await c.join(code)
            await c.click(AGREE)
            for _ in range(100):
                if srv.session(code).session.phase() != "consent":
                    break
                await asyncio.sleep(0.05)
            await asyncio.to_thread(skip_to_end, srv, code)
            await c.wait_for(lambda m: END_TEXT in str(m.get("props", {}).get("_markdown", "")))

    run_async(visit())


def row(srv, served: int) -> dict:  # type: ignore[no-untyped-def]
    gc.collect()
    return {
        "served": served,
        "threads": threading.active_count(),
        "registry": len(srv.sessions()),
        "rss_mb": round(rss_mb(), 1),
        "objects": len(gc.get_objects()),
    }


def show(r: dict) -> None:
    print(
        f"{r['served']:5d} served  threads {r['threads']:4d}  registry {r['registry']:4d}"
        f"  RSS {r['rss_mb']:7.1f} MB  objects {r['objects']:8d}",
        flush=True,
    )


def run(args: argparse.Namespace) -> dict:
    has_grace = "finished_grace_s" in inspect.signature(StudyServer).parameters
    # every tab comes from 127.0.0.1, one after another: the new-tab gate (its own tests) is off
    roomy = FirewallConfig(new_tabs_per_s=None, accept_burst=500.0, accept_total_per_s=500.0)
    kw: dict = {
        "port_firewall": Firewall(roomy),
        "throttle": JoinThrottle(per_address=100_000, per_server=100_000),  # one code a tab
    }
    if has_grace:
        kw["finished_grace_s"] = args.grace
    with tempfile.TemporaryDirectory() as d:
        rs = start_server(d, server_kw=kw)
        srv = rs.server
        rows = [row(srv, 0)]
        show(rows[-1])
        t0 = time.monotonic()
        try:
            for n in range(1, args.sessions + 1):
                serve_one(srv, f"P{n:04d}", tab=args.tabs)
                if n % args.every == 0:
                    rows.append(row(srv, n))
                    show(rows[-1])
            if has_grace:  # the last ones' grace, then the sweeper's round
                wait_until(lambda: not srv.sessions(), timeout=args.grace + 60)
            else:
                time.sleep(args.grace + 1)
            rows.append(row(srv, args.sessions))
            show(rows[-1])
        finally:
            rs.stop()
    return {
        "code": "with finished_grace_s" if has_grace else "without (finished sessions stay)",
        "sessions": args.sessions,
        "tabs": args.tabs,
        "seconds": round(time.monotonic() - t0, 1),
        "first": rows[0],
        "last": rows[-1],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=100, help="participants served")
    parser.add_argument("--every", type=int, default=10, help="sessions between lines")
    parser.add_argument("--tabs", action="store_true", help="each with a tab that joins")
    parser.add_argument("--grace", type=float, default=1.0, help="finished_grace_s, s")
    parser.add_argument("--code", help="another checkout to measure (e.g. main's)")
    args = parser.parse_args()
    print(json.dumps(run(args)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

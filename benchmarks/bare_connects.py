"""What a flood of bare TCP connects (connect, close, nothing sent) costs the study server.

``python -m study serve`` runs in its own process (the real-time class at ``--realtime``, as a
lab runs it); after ``--idle`` seconds of the server alone, ``--procs`` processes connect and
close as fast as they can from 127.0.0.2 (one address, far over its accept gate) for
``--seconds``, while a probe from 127.0.0.1 loads the page every 2 s. Printed: the
server's CPU (cores) alone and under the flood, the connects a second the flood made, the
server's CPU per connect (microseconds), and the probe's page loads (median and worst, ms).

``--code DIR`` runs another checkout's server (``git archive main | tar -x -C DIR``), side by side.

Usage: ``.venv/bin/python benchmarks/bare_connects.py [--procs 2] [--seconds 10] [--realtime 10]
[--code DIR]``.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SERVE = (sys.executable, "-m", "study", "serve", "--host", "127.0.0.1")
RESET = struct.pack("ii", 1, 0)
"""The flood closes with a reset, as an attacker would: a plain close leaves its port in
TIME_WAIT for a minute and one address runs out of ports at about 470 connects a second."""
PROBE_EVERY_S = 2.0
"""A page load every 2 s: a person's reloads, well inside the accept gate's 1 a second and burst."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _flood(port: int, seconds: float, out: mp.Queue) -> None:
    made = failed = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            with socket.socket() as s:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, RESET)
                s.bind(("127.0.0.2", 0))
                s.connect(("127.0.0.1", port))
            made += 1
        except OSError:
            failed += 1
    out.put((made, failed))


def _probe(url: str, stop: threading.Event, loads_ms: list[float]) -> None:
    while not stop.wait(PROBE_EVERY_S):
        start = time.perf_counter()
        try:
            with urllib.request.urlopen(url, timeout=10) as r:
                r.read()
            loads_ms.append(1000 * (time.perf_counter() - start))
        except OSError:
            loads_ms.append(float("inf"))


def _wait_serving(port: int, server: subprocess.Popen[bytes]) -> None:
    for _ in range(600):
        if server.poll() is not None:
            raise SystemExit(f"the server exited with {server.returncode}")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            time.sleep(0.1)
    raise SystemExit("the server did not start within 60 s")


def measure(*, code: Path, procs: int, seconds: float, idle_s: float, realtime: int) -> dict:
    port, console = _free_port(), _free_port()
    with tempfile.TemporaryDirectory() as tmp:
        options = {
            "--db": f"{tmp}/study.db",
            "--port": str(port),
            "--experimenter-port": str(console),
            "--realtime": str(realtime),
            "--log": f"{tmp}/serve.log",
        }
        server = subprocess.Popen(
            [*SERVE, *(part for item in options.items() for part in item)],
            cwd=code,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            _wait_serving(port, server)
            time.sleep(2.0)  # its first page build and imports done
            c0 = _cpu_s(server.pid)
            time.sleep(idle_s)
            idle = (_cpu_s(server.pid) - c0) / idle_s
            out: mp.Queue = mp.Queue()
            flood = [mp.Process(target=_flood, args=(port, seconds, out)) for _ in range(procs)]
            stop, loads = threading.Event(), []
            probe = threading.Thread(target=_probe, args=(f"http://127.0.0.1:{port}/", stop, loads))
            c0, t0 = _cpu_s(server.pid), time.monotonic()
            probe.start()
            for p in flood:
                p.start()
            results = [out.get() for _ in flood]
            for p in flood:
                p.join()
            c1, t1 = _cpu_s(server.pid), time.monotonic()
            stop.set()
            probe.join()
        finally:
            server.terminate()
            server.wait(10)
    made = sum(m for m, _ in results)
    return {
        "server_idle_core": round(idle, 3),
        "server_flood_core": round((c1 - c0) / (t1 - t0), 3),
        "connects_per_s": round(made / (t1 - t0)),
        "failed_connects": sum(f for _, f in results),
        "server_us_per_connect": round(1e6 * (c1 - c0 - idle * (t1 - t0)) / max(1, made), 1),
        "page_loads": len(loads),
        "page_loads_failed": sum(1 for x in loads if x == float("inf")),
        "page_load_ms_median": round(statistics.median(loads), 1) if loads else None,
        "page_load_ms_worst": round(max(loads), 1) if loads else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--procs", type=int, default=2, help="flooding processes")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--idle", type=float, default=5.0, help="seconds of the server alone")
    parser.add_argument("--realtime", type=int, default=10, help="serve --realtime (0: off)")
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout to serve")
    args = parser.parse_args()
    figures = measure(
        code=args.code.resolve(),
        procs=args.procs,
        seconds=args.seconds,
        idle_s=args.idle,
        realtime=args.realtime,
    )
    print(json.dumps({"code": str(args.code), "realtime": args.realtime, **figures}))


if __name__ == "__main__":
    main()

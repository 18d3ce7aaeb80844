"""Where a command's CPU goes, Chromium's processes and threads included (issue 24.4).

``/usr/bin/time`` misses Chromium: its GPU process and renderers are children of the zygote,
reaped by the browser, not by the command. This script runs the command and samples
``/proc`` every ``--interval`` seconds: each descendant's CPU (user + system, the last value
seen before it ended, so a process that lives less than one interval is missed) by program,
Chromium's split by process type, and the busiest Chromium threads::

    .venv/bin/python benchmarks/chromium_cpu.py -- .venv/bin/python -m pytest -n 0 \\
        tests/browser/test_keys_and_pause.py

Chromium rewrites its processes' command lines into one string (``/usr/lib/chromium/chromium
--type=renderer ...``), so the type is read from that string, not from a separate argument;
forked from the zygote, a renderer's parent is the zygote, not the browser. Threads worth
knowing (the twelfth and thirteenth sessions): ``gpu / Thread<NN>`` are SwiftShader's workers
running the page's WebGL shaders (the scene's pixels), ``gpu / VizCompositorTh`` the software
compositor, ``renderer / chromium`` the page's JavaScript (viser's client applying the scene
updates), ``renderer / DedicatedWorker`` its websocket decoder. Compare CPU seconds side by side
with another version in the same minutes, not wall time, on a shared machine.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import time
from collections import defaultdict
from dataclasses import dataclass

TICK = os.sysconf("SC_CLK_TCK")
ENDED = "(ended: command line gone)"


@dataclass(frozen=True)
class Proc:
    ppid: int
    cpu_s: float
    title: str
    start: int
    """When it started (clock ticks after boot): with the pid, which process it is."""


def _stat_cpu(text: str) -> tuple[int, float, int]:
    """(ppid, user + system CPU seconds, start time) from a ``/proc/.../stat`` line."""
    rest = text.rsplit(")", 1)[1].split()
    return int(rest[1]), (int(rest[11]) + int(rest[12])) / TICK, int(rest[19])


def snapshot() -> dict[int, Proc]:
    procs: dict[int, Proc] = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat") as f:
                ppid, cpu, start = _stat_cpu(f.read())
            with open(f"/proc/{name}/cmdline") as f:
                title = f.read().replace("\0", " ").strip()
        except OSError:
            continue
        procs[int(name)] = Proc(ppid, cpu, title, start)
    return procs


def descendants(root: int, procs: dict[int, Proc]) -> set[int]:
    children: dict[int, list[int]] = defaultdict(list)
    for pid, p in procs.items():
        children[p.ppid].append(pid)
    out, todo = set(), [root]
    while todo:
        pid = todo.pop()
        if pid in out:
            continue
        out.add(pid)
        todo.extend(children.get(pid, ()))
    return out


def kind(title: str) -> str:
    """``chromium:<type>`` for Chromium's processes (``browser`` without a type), else the
    program's name and first argument."""
    words = title.split()
    if not words:
        return ENDED
    program = os.path.basename(words[0])
    if program == "chromium":
        typ = next((w[7:] for w in words if w.startswith("--type=")), "browser")
        return f"chromium:{typ}"
    return " ".join([program, *words[1:3]])[:60]


def threads(pid: int) -> dict[str, float]:
    """CPU seconds of ``pid``'s live threads, summed by thread name."""
    out: dict[str, float] = defaultdict(float)
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                text = f.read()
            out[text.split("(", 1)[1].rsplit(")", 1)[0]] += _stat_cpu(text)[1]
    except OSError:
        pass
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--interval", type=float, default=0.25, help="seconds between samples")
    ap.add_argument("--threads", type=int, default=15, help="Chromium threads to print")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = ap.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        ap.error("give the command to run after --")

    t0 = time.monotonic()
    child = subprocess.Popen(command)
    last: dict[int, tuple[float, str]] = {}
    per_thread: dict[tuple[int, str, str], float] = {}
    while child.poll() is None:
        procs = snapshot()
        for pid in descendants(child.pid, procs):
            p = procs.get(pid)
            if p is None:
                continue
            k = kind(p.title)
            if pid in last and k == ENDED:  # an ended process keeps the kind it was seen as
                k = last[pid][1]
            last[pid] = (max(last.get(pid, (0.0, k))[0], p.cpu_s), k)
            if k.startswith("chromium:"):
                for name, cpu in threads(pid).items():
                    key = (pid, k, name)
                    per_thread[key] = max(per_thread.get(key, 0.0), cpu)
        time.sleep(args.interval)
    wall = time.monotonic() - t0

    by_kind: dict[str, float] = defaultdict(float)
    for cpu, k in last.values():
        by_kind[k] += cpu
    chromium = sum(v for k, v in by_kind.items() if k.startswith("chromium:"))
    print(
        f"wall {wall:.1f} s, CPU {sum(by_kind.values()):.1f} s "
        f"(Chromium {chromium:.1f} s), exit code {child.returncode}"
    )
    for k, v in sorted(by_kind.items(), key=lambda kv: -kv[1]):
        print(f"  {v:7.1f} s  {k}")
    by_thread: dict[tuple[str, str], float] = defaultdict(float)
    for (_, k, name), cpu in per_thread.items():
        by_thread[(k, name)] += cpu
    print("Chromium's busiest threads:")
    for (k, name), v in sorted(by_thread.items(), key=lambda kv: -kv[1])[: args.threads]:
        print(f"  {v:7.1f} s  {k} / {name}")


if __name__ == "__main__":
    main()

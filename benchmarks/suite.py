"""Time the whole test suite as CI runs it, side by side for revisions and worker counts.

Issue 24.4: the README's test command within 6 minutes on 2 cores. Each run starts from what a
clean clone has: a detached worktree of the revision (``git worktree add``), emptied of every
untracked file (``git clean -fdx``: no bytecode, no numba cache, no pytest cache), then what
``.ci/setup`` does after installing (``.ci/prepare``: the control tick's kernels compiled once,
the repository's bytecode; ``python -m app.warm_up`` in revisions without it), then ``python -m
pytest -n N --maxprocesses=N``, with the Python that runs this script (from the worktree it
imports the worktree's code; the packages are this one's). While pytest runs, ``/proc/stat``
is read every second: how busy both cores were, and how many CPU seconds the run's processes used
(pytest, its workers and everything they start, Chromium included: each process's last reading,
sampled every half second, so up to half a second of each process's end is missed, and a process
that lives less than that entirely: a small bias, alike for revisions that start alike). On a shared machine
other jobs change the wall time a lot and the CPU seconds little: compare those.

Runs alternate (revision by revision, worker count by worker count, ``--runs`` rounds), so
versions compared share the same minutes of a shared machine. Prints one row a run, a summary
per revision and worker count (median and worst), and as its last line one JSON object::

    .venv/bin/python benchmarks/suite.py --rev main --rev HEAD --workers 3 --workers 4 --runs 2

``--` separates extra pytest arguments (``-- -m "not browser"``). The worktrees are made
under a temporary folder and removed at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Self

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.chromium_cpu import descendants, snapshot  # noqa: E402

PYTHON = Path(sys.executable)
"""The Python that runs this script runs the suite (``.venv/bin/python``: the project's)."""
SUMMARY = re.compile(r"=+ (.*) in ([0-9.]+)s")


@dataclass(frozen=True)
class Run:
    rev: str
    commit: str
    workers: int
    setup_s: float
    wall_s: float
    pytest_s: float | None
    """The time pytest printed (its session, without interpreter start-up)."""
    busy: float
    """Share of both cores busy while pytest ran (0..1)."""
    cpu_s: float
    """CPU seconds of pytest's process tree (:class:`TreeCpu`)."""
    outcome: str
    exit_code: int
    load_before: float


class Sampler(ABC):
    """A thread that calls :meth:`sample` every ``interval`` seconds while in a ``with``
    block (once on entering)."""

    def __init__(self, *, interval: float) -> None:
        self.interval = interval
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    @abstractmethod
    def sample(self) -> None:
        """Read what the sampler measures once."""

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            try:
                self.sample()
            except OSError:  # /proc unreadable for a moment: the next sample counts
                continue

    def __enter__(self) -> Self:
        self.sample()
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join()


class CpuSampler(Sampler):
    """How busy the machine's cores were, from ``/proc/stat`` once a second."""

    def __init__(self) -> None:
        super().__init__(interval=1.0)
        self._busy = 0
        self._total = 0
        self._prev: tuple[int, int] | None = None

    def sample(self) -> None:
        with open("/proc/stat", encoding="ascii") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
        total, idle = sum(fields), fields[3] + fields[4]  # idle + iowait
        if self._prev is not None:
            total0, idle0 = self._prev
            self._total += total - total0
            self._busy += (total - total0) - (idle - idle0)
        self._prev = total, idle

    @property
    def busy(self) -> float:
        return self._busy / self._total if self._total else 0.0


class TreeCpu(Sampler):
    """CPU seconds used by a process and all its descendants, sampled from ``/proc`` every
    ``interval`` seconds (Chromium's renderers are not waited for by the command, so
    ``getrusage`` misses them; ``benchmarks/chromium_cpu.py`` splits the same figure by
    program)."""

    def __init__(self, pid: int, *, interval: float = 0.5) -> None:
        super().__init__(interval=interval)
        self.pid = pid
        self._last: dict[tuple[int, int], float] = {}  # (pid, start time) -> CPU s

    def sample(self) -> None:
        procs = snapshot()
        for pid in descendants(self.pid, procs):
            p = procs.get(pid)
            if p is not None:
                key = (pid, p.start)
                self._last[key] = max(self._last.get(key, 0.0), p.cpu_s)

    @property
    def cpu_s(self) -> float:
        return sum(self._last.values())


def git(*args: str, cwd: Path = ROOT) -> str:
    return subprocess.run(
        ["git", *args], cwd=cwd, check=True, capture_output=True, text=True
    ).stdout.strip()


def run_once(tree: Path, rev: str, workers: int, extra: list[str], log: Path) -> Run:
    """One run in ``tree`` (a worktree at ``rev``) from a clean clone's state."""
    git("clean", "-fdxq", cwd=tree)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    if (tree / ".ci" / "prepare").exists():  # what .ci/setup does after installing
        prepare = ["bash", ".ci/prepare"]
    else:  # revisions before it: the kernels only
        prepare = [str(PYTHON), "-m", "app.warm_up"]
    env = {**os.environ, "PYTHON": str(PYTHON)}
    subprocess.run(prepare, cwd=tree, env=env, check=True, capture_output=True)
    setup_s = time.perf_counter() - start
    command = [str(PYTHON), "-m", "pytest", "-n", str(workers), f"--maxprocesses={workers}"]
    with log.open("w") as out, CpuSampler() as cpu:
        start = time.perf_counter()
        with subprocess.Popen([*command, *extra], cwd=tree, stdout=out, stderr=out) as child:
            try:
                with TreeCpu(child.pid) as tree_cpu:
                    child.wait()
            except BaseException:  # Ctrl-C or a sampler error: no pytest left running
                child.kill()
                raise
        wall_s = time.perf_counter() - start
    lines = log.read_text(errors="replace").splitlines()
    match = next((m for m in map(SUMMARY.search, reversed(lines)) if m), None)
    return Run(
        rev=rev,
        commit=git("rev-parse", "--short", "HEAD", cwd=tree),
        workers=workers,
        setup_s=round(setup_s, 1),
        wall_s=round(wall_s, 1),
        pytest_s=None if match is None else float(match[2]),
        busy=round(cpu.busy, 3),
        cpu_s=round(tree_cpu.cpu_s, 1),
        outcome="no summary line" if match is None else match[1],
        exit_code=child.returncode,
        load_before=round(load, 2),
    )


def minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {seconds % 60:04.1f} s"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rev", action="append", help="revision (repeat; default HEAD)")
    parser.add_argument("--workers", type=int, action="append", help="pytest-xdist workers")
    parser.add_argument("--runs", type=int, default=1, help="rounds over every combination")
    parser.add_argument("--logs", type=Path, help="keep each run's pytest output here")
    parser.add_argument("pytest_args", nargs="*", help="after --: extra pytest arguments")
    args = parser.parse_args()
    revs, counts = args.rev or ["HEAD"], args.workers or [3]
    if args.runs < 1 or min(counts) < 1:
        parser.error("--runs and --workers must be at least 1")
    base = Path(tempfile.mkdtemp(prefix="suite-"))
    logs = args.logs or base / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    trees = {}
    runs: list[Run] = []
    try:
        for k, rev in enumerate(revs):
            trees[rev] = base / f"tree{k}"
            git("worktree", "add", "--detach", "-f", str(trees[rev]), rev)
        print(
            f"{'rev':>10} {'commit':>9} {'n':>2} {'setup':>6} {'pytest':>14} {'busy':>5}"
            f" {'CPU s':>6}  outcome"
        )
        for _ in range(args.runs):
            for rev in revs:
                for n in counts:
                    log = logs / f"{len(runs):02d}-{rev.replace('/', '_')}-n{n}.txt"
                    run = run_once(trees[rev], rev, n, args.pytest_args, log)
                    runs.append(run)
                    took = minutes(run.pytest_s if run.pytest_s is not None else run.wall_s)
                    print(
                        f"{rev:>10} {run.commit:>9} {n:>2} {run.setup_s:5.1f}s {took:>14}"
                        f" {run.busy:5.0%} {run.cpu_s:6.0f}  {run.outcome}"
                        f" (load {run.load_before} before)",
                        flush=True,
                    )
    finally:
        for tree in trees.values():
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT)
        if args.logs is None:
            shutil.rmtree(base, ignore_errors=True)
    summary = {}
    print("\nper revision and worker count: pytest's time, median (worst); cores busy; CPU s")
    for rev in revs:
        for n in counts:
            mine = [r for r in runs if r.rev == rev and r.workers == n]
            times = [r.pytest_s if r.pytest_s is not None else r.wall_s for r in mine]
            failed = [r.outcome for r in mine if r.exit_code != 0]
            summary[f"{rev} n={n}"] = {
                "median_s": statistics.median(times),
                "worst_s": max(times),
                "busy": statistics.median(r.busy for r in mine),
                "cpu_s": statistics.median(r.cpu_s for r in mine),
                "failed_runs": len(failed),
            }
            print(
                f"  {rev} with {n} workers: {minutes(statistics.median(times))}"
                f" ({minutes(max(times))}), busy {statistics.median(r.busy for r in mine):.0%},"
                f" {statistics.median(r.cpu_s for r in mine):.0f} CPU s (median),"
                f" {len(failed)} of {len(mine)} runs failed"
            )
    print(json.dumps({"runs": [asdict(r) for r in runs], "summary": summary}))
    return 0 if all(r.exit_code == 0 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())

"""How fast simulated participants run through the whole study (training included).

    .venv/bin/python benchmarks/simulate.py [--small 8] [--large 64] [--workers 2] [--seed 1] \
        [--engine local|dask|both]

Measures, each into a fresh temporary store, with the real session engine and control loop:
``--small`` participants with one process, then ``--large`` participants with one process and
with ``--workers`` processes (the speed-up), for each engine asked for (``local``: this process
or processes sharing the store; ``dask``: a ``LocalCluster`` of 1 and of ``--workers`` worker
processes, this process merging every participant). For the Dask engine it also measures its
per-task overhead two ways: the round trip of a no-op task on a 1-worker ``LocalCluster``
(scheduling and transport alone), and the extra wall time per participant of the 1-worker Dask
run over the 1-worker local run (cluster start-up, scratch store, shipping and merging the
participant). Prints a table (per-participant wall time median and p99, simulated time,
outcomes) and, as its last line, one JSON object. The machine's load average is printed too: on
a shared 2-core machine other jobs slow every figure down.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from study.simulated.runner import SimulationReport, simulate  # noqa: E402


def _cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def measure(
    *, participants: int, workers: int, seed: int, protocol: Path, tmp: Path, engine: str
) -> dict[str, Any]:
    db = tmp / f"sim-{engine}-{participants}-{workers}.db"
    if db.exists():
        raise SystemExit(f"{db} exists; pass an empty --keep folder")
    load = os.getloadavg()[0]
    cpu0 = _cpu_s()
    report: SimulationReport = simulate(
        protocol_path=protocol,
        db=db,
        participants=participants,
        seed=seed,
        workers=workers,
        progress=True,
        engine=engine,
    )
    per = np.array([r.wall_s for r in report.results])
    ticks_s = report.sim_s  # simulated seconds (100 control ticks per second)
    return {
        "engine": engine,
        "participants": participants,
        "workers": workers,
        "wall_s": round(report.wall_s, 2),
        "cpu_s": round(_cpu_s() - cpu0, 2),
        "per_participant_median_s": round(float(np.median(per)), 2),
        "per_participant_p99_s": round(float(np.percentile(per, 99)), 2),
        "trials": report.trials,
        "ratings": report.ratings,
        "simulated_s": round(ticks_s, 1),
        "realtime_factor": round(ticks_s / report.wall_s, 1),
        "outcomes": report.outcomes,
        "errors": len(report.errors),
        "load_avg_1min_before": round(load, 2),
    }


def noop_task_ms(*, tasks: int = 500) -> dict[str, float]:
    """Round trip of ``tasks`` no-op tasks submitted at once to a 1-worker ``LocalCluster``:
    what the Dask engine costs per task before any simulation (median of 3 batches)."""
    from distributed import Client, LocalCluster, wait

    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as client,
    ):
        start = time.perf_counter()
        client.submit(int, 0, pure=False).result()
        first = time.perf_counter() - start
        per: list[float] = []
        for _ in range(3):
            start = time.perf_counter()
            wait(client.map(int, range(tasks), pure=False))
            per.append((time.perf_counter() - start) / tasks * 1e3)
    return {"noop_task_ms": round(float(np.median(per)), 3), "first_task_ms": round(first * 1e3, 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", type=int, default=8)
    parser.add_argument("--large", type=int, default=64, help="0 to skip the scaling runs")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--protocol", type=Path, default=ROOT / "protocols" / "dragan2013.toml")
    parser.add_argument("--keep", type=Path, default=None, help="write the stores here (kept)")
    parser.add_argument("--engine", choices=["local", "dask", "both"], default="both")
    args = parser.parse_args()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="bench-simulate-") as scratch:
        tmp = args.keep or Path(scratch)
        tmp.mkdir(parents=True, exist_ok=True)
        engines = ["local", "dask"] if args.engine == "both" else [args.engine]
        runs = [(engines[0], args.small, 1)] if args.small else []
        if args.large:
            runs += [(e, args.large, w) for e in engines for w in (1, args.workers)]
        for engine, n, w in runs:
            print(f"-- {engine}: {n} participants, {w} worker(s)", file=sys.stderr)
            rows.append(
                measure(
                    participants=n,
                    workers=w,
                    seed=args.seed,
                    protocol=args.protocol,
                    tmp=Path(tmp),
                    engine=engine,
                )
            )
    head = (
        f"{'engine':>6} {'participants':>12} {'workers':>7} {'wall_s':>8} {'cpu_s':>8} {'median_s':>9} "
        f"{'p99_s':>7} {'sim_s':>8} {'x_real':>7} {'load':>5}  outcomes"
    )
    print(head)
    for r in rows:
        print(
            f"{r['engine']:>6} {r['participants']:>12} {r['workers']:>7} {r['wall_s']:>8} {r['cpu_s']:>8} "
            f"{r['per_participant_median_s']:>9} {r['per_participant_p99_s']:>7} "
            f"{r['simulated_s']:>8} {r['realtime_factor']:>7} {r['load_avg_1min_before']:>5}  "
            f"{r['outcomes']}"
        )
    summary: dict[str, Any] = {"runs": rows}
    if args.small:
        summary["small_wall_s"] = rows[0]["wall_s"]
    if args.large:
        large = {(r["engine"], r["workers"]): r for r in rows if r["participants"] == args.large}
        for engine in engines:
            one, many = large[(engine, 1)], large[(engine, args.workers)]
            summary[f"{engine}_speedup"] = round(one["wall_s"] / many["wall_s"], 2)
            summary[f"{engine}_large_wall_s_1_worker"] = one["wall_s"]
            summary[f"{engine}_large_wall_s_{args.workers}_workers"] = many["wall_s"]
        if "dask" in engines:
            summary.update(noop_task_ms())
            if "local" in engines:
                extra = large[("dask", 1)]["wall_s"] - large[("local", 1)]["wall_s"]
                summary["dask_overhead_per_participant_s"] = round(extra / args.large, 3)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

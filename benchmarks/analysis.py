"""Speed of the analysis package: the full report and the anova command.

Targets (issue): the full report for 8 participants in at most 15 s; the anova command on
1,000 simulated participants x 8 cells in at most 5 s; the power command with its defaults
(N = 8, 12, 16, 24, 32; B = 1000; H1 and H2 in both forms) in at most 60 s (issue 13); the
mixed-model anova (--mixed) on the same 1,000 x 8 data, printed for reference. Both are timed end to end as commands
(`python -m analysis report|anova`, interpreter start included), plus the in-process parts.
Data are synthetic (analysis.synthetic: 8 participants, 100 Hz user-target samples, about
28 s per trial) unless --db or --export-dir names a real study.

    .venv/bin/python benchmarks/analysis.py [--repeats 3] [--db PATH | --export-dir DIR]

Prints a table and, as its last line, one JSON object.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _summary(times: list[float]) -> dict[str, float]:
    return {
        "median_s": statistics.median(times),
        "p99_s": float(np.percentile(times, 99)),
        "min_s": min(times),
        "max_s": max(times),
        "n": len(times),
    }


CPU: list[float] = []  # CPU seconds (user + sys) of each command run, load-independent


def _run(cmd: list[str]) -> float:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return elapsed


def anova_csv(path: Path, n: int = 1000, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    cells = list(itertools.product(["easy", "hard"], ["right", "wrong"], ["timid", "aggressive"]))
    rows = []
    for s in range(n):
        base = rng.normal(0, 5)
        for dif, cor, mode in cells:
            y = 20 + base + 10 * (dif == "hard") + 15 * (cor == "wrong") * (mode == "aggressive")
            rows.append((f"S{s:04d}", dif, cor, mode, y + rng.normal(0, 6), rng.normal(40, 8)))
    pd.DataFrame(
        rows, columns=["subject", "difficulty", "correctness", "mode", "time_s", "skill"]
    ).to_csv(path, index=False)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--db")
    src.add_argument("--export-dir")
    args = ap.parse_args()
    py = sys.executable
    results: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        if args.db or args.export_dir:
            source = ["--db", args.db] if args.db else ["--export-dir", args.export_dir]
            label = args.db or args.export_dir
        else:
            from analysis.synthetic import synthetic_tables

            tables = synthetic_tables(8, seed=0, rate_hz=100.0)
            exp = tmpd / "export"
            exp.mkdir()
            tables["trials"].to_csv(exp / "trials.csv", index=False)
            tables["samples"].to_parquet(exp / "samples.parquet")
            tables["ratings"].to_csv(exp / "ratings.csv", index=False)
            source, label = ["--export-dir", str(exp)], "synthetic, 8 participants, 100 Hz"
            results["samples"] = len(tables["samples"])
        CPU.clear()
        report = [
            _run([py, "-m", "analysis", "report", *source, "--out", str(tmpd / "rep")])
            for _ in range(args.repeats)
        ]
        results["report_command"] = {
            **_summary(report),
            "target_s": 15.0,
            "data": label,
            "cpu_s_median": statistics.median(CPU),
        }

        from analysis.load import load_tables
        from analysis.report import write_report

        parts = {"load": [], "write_report": []}
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            st = load_tables(
                db=args.db, export_dir=args.export_dir or (None if args.db else source[1])
            )
            t1 = time.perf_counter()
            write_report(st, tmpd / "rep2")
            t2 = time.perf_counter()
            parts["load"].append(t1 - t0)
            parts["write_report"].append(t2 - t1)
        results["report_in_process"] = {k: _summary(v) for k, v in parts.items()}

        csv = tmpd / "anova.csv"
        anova_csv(csv)
        base = [
            py,
            "-m",
            "analysis",
            "anova",
            "--csv",
            str(csv),
            "--dv",
            "time_s",
            "--subject",
            "subject",
            "--within",
            "difficulty",
            "correctness",
            "mode",
        ]
        CPU.clear()
        rm = [_run(base) for _ in range(max(5, args.repeats))]
        rm_cpu = statistics.median(CPU)
        CPU.clear()
        cov = [_run([*base, "--covariates", "skill"]) for _ in range(max(5, args.repeats))]
        results["anova_command_rm_1000x8"] = {
            **_summary(rm),
            "target_s": 5.0,
            "cpu_s_median": rm_cpu,
        }
        results["anova_command_covariates_1000x8"] = {
            **_summary(cov),
            "target_s": 5.0,
            "cpu_s_median": statistics.median(CPU),
        }
        CPU.clear()
        mixed = [
            _run([*base, "--covariates", "skill", "--mixed"]) for _ in range(max(3, args.repeats))
        ]
        results["anova_command_mixed_1000x8"] = {
            **_summary(mixed),
            "cpu_s_median": statistics.median(CPU),
        }
        CPU.clear()
        power = [
            _run([py, "-m", "analysis", "power", *source, "--out", str(tmpd / "power")])
            for _ in range(args.repeats)
        ]
        results["power_command_default"] = {
            **_summary(power),
            "target_s": 60.0,
            "data": label,
            "cpu_s_median": statistics.median(CPU),
        }

        from analysis.rm_anova import rm_anova

        data = pd.read_csv(csv)
        inproc = []
        for _ in range(20):
            t0 = time.perf_counter()
            rm_anova(
                data, dv="time_s", subject="subject", within=["difficulty", "correctness", "mode"]
            )
            inproc.append(time.perf_counter() - t0)
        results["rm_anova_in_process_1000x8"] = _summary(inproc)

    print(f"{'measure':40s} {'median s':>9s} {'p99 s':>8s} {'CPU s':>7s} {'target':>7s}")
    for key, val in results.items():
        if isinstance(val, dict) and "median_s" in val:
            cpu = val.get("cpu_s_median")
            print(
                f"{key:40s} {val['median_s']:9.3f} {val['p99_s']:8.3f} "
                f"{'' if cpu is None else f'{cpu:.3f}':>7s} {val.get('target_s', ''):>7}"
            )
        elif isinstance(val, dict):
            for sub, v in val.items():
                print(f"{key + '.' + sub:40s} {v['median_s']:9.3f} {v['p99_s']:8.3f}")
    results["load_average_1_5_15"] = list(os.getloadavg())
    results["cpus"] = os.cpu_count()
    print(
        f"load average {results['load_average_1_5_15']} on {os.cpu_count()} CPUs "
        "(other processes slow every figure down)"
    )
    print(json.dumps({"benchmark": "analysis", **results}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

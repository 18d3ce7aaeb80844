"""The paper's timing result, store by store and pooled: what issue 20.6 compares with the paper.

    .venv/bin/python benchmarks/study_result.py STORE.db [STORE.db ...] [--charge]

For each store (one simulated or real study of the paper's 2 x 2 x 2 design) it prints: the mean
task time; the three main effects as differences of unweighted marginal means (s) with the
factorial ANOVA's F(1, 53) (``analysis.timing``, the report's model with covariates); the
aggressiveness x correctness interaction F and its size in seconds (aggressive's cost when
wrong minus its cost when right); the four situations' means (right/wrong x timid/aggressive);
and per condition the success share, knocks and timeouts (``analysis.descriptives``). A last
table pools every store's trials per condition. ``--charge`` adds, from the samples, who was in
charge of each condition's runs: seconds with ``alpha > 0`` toward the wrong object and toward
the target, seconds the wrong object was predicted. The paper's values are printed beside; the
last line is every store's figures as one JSON list. No
simulation here: run ``python -m study simulate`` first (commands in benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.descriptives import condition_descriptives  # noqa: E402
from analysis.load import load_tables, task_cells  # noqa: E402
from analysis.timing import timing_analysis  # noqa: E402

PAPER = {
    "mean_s": 28.0,
    "hard - easy": (22.9, 18.45),
    "wrong - right": (30.1, 31.88),
    "aggressive - timid": (19.4, 13.2),
    "correctness:mode F": 36.28,
}
SITUATIONS = (
    ("right", "aggressive"),
    ("right", "timid"),
    ("wrong", "aggressive"),
    ("wrong", "timid"),
)


def one_store(db: Path) -> dict[str, Any]:
    tables = load_tables(db=db)
    cells, _ = task_cells(tables.trials)
    timing = timing_analysis(cells)
    table = timing.ancova.table.set_index("effect")
    effects = {}
    for row in timing.main_effects.itertuples():
        effects[row.contrast] = (
            float(row.mean_diff),
            float(table.loc[row.effect, "F"]),
        )
    m = cells.groupby(["correctness", "mode"], observed=True)["duration_s"].mean()
    situations = {f"{c}-{a}": float(m[c, a]) for c, a in SITUATIONS}
    cost = (m["wrong", "aggressive"] - m["wrong", "timid"]) - (
        m["right", "aggressive"] - m["right", "timid"]
    )
    d = condition_descriptives(tables)
    d = d[d["task"] != "practice"]
    conditions = {
        f"{r.task} {r.mode}": {
            "runs": int(r.runs),
            "successes": int(r.successes),
            "knocks": int(r.knocks),
            "timeouts": int(r.timeouts),
            "other_failures": dict(r.other_failures),
            "mean_s": float(r.time_all_mean),
        }
        for r in d.itertuples()
    }
    return {
        "store": str(db),
        "participants": int(cells["participant"].nunique()),
        "mean_s": float(cells["duration_s"].mean()),
        "effects": effects,
        "interaction_F": float(table.loc["correctness:mode", "F"]),
        "interaction_s": float(cost),
        "situations": situations,
        "slowest": max(situations, key=situations.get),
        "conditions": conditions,
    }


def pooled(results: list[dict[str, Any]]) -> pd.DataFrame:
    rows: dict[str, dict[str, Any]] = {}
    for res in results:
        for cond, c in res["conditions"].items():
            r = rows.setdefault(
                cond, {"runs": 0, "successes": 0, "knocks": 0, "timeouts": 0, "time": 0.0}
            )
            for k in ("runs", "successes", "knocks", "timeouts"):
                r[k] += c[k]
            r["time"] += c["mean_s"] * c["runs"]
    out = pd.DataFrame.from_dict(rows, orient="index")
    out["mean_s"] = out["time"] / out["runs"]
    return out.drop(columns="time")


def markdown(results: list[dict[str, Any]]) -> str:
    paths = [Path(r["store"]) for r in results]
    parents = [p.parent.name for p in paths]
    shared = len(set(parents)) < len(parents)  # stores of one folder: name them by file
    names = [p.stem if shared or not p.parent.name else p.parent.name for p in paths]
    lines = ["| measure | " + " | ".join(names) + " | paper |"]
    lines.append("| --- " * (len(results) + 2) + "|")

    def row(label: str, values: list[str], paper: str) -> None:
        lines.append(f"| {label} | " + " | ".join(values) + f" | {paper} |")

    row("mean time (s)", [f"{r['mean_s']:.1f}" for r in results], "about 28")
    for eff in ("hard - easy", "wrong - right", "aggressive - timid"):
        s, f = PAPER[eff]
        row(
            f"{eff}: s (F)",
            [f"{r['effects'][eff][0]:+.1f} ({r['effects'][eff][1]:.2f})" for r in results],
            f"+{s} ({f})",
        )
    row(
        "aggressive x correctness: F (cost of aggressive when wrong - when right, s)",
        [f"{r['interaction_F']:.2f} ({r['interaction_s']:+.1f})" for r in results],
        f"{PAPER['correctness:mode F']}",
    )
    for sit in ("right-aggressive", "right-timid", "wrong-aggressive", "wrong-timid"):
        row(
            f"{sit} (s)",
            [
                ("**" if r["slowest"] == sit else "")
                + f"{r['situations'][sit]:.1f}"
                + ("**" if r["slowest"] == sit else "")
                for r in results
            ],
            "slowest" if sit == "wrong-aggressive" else "",
        )
    lines.append("")
    lines.append("| condition | runs | success | knocks | timeouts | mean time (s) |")
    lines.append("| --- | --- | --- | --- | --- | --- |")
    for cond, r in pooled(results).iterrows():
        runs, ok = int(r["runs"]), int(r["successes"])
        lines.append(
            f"| {cond} | {runs} | {ok / runs:.2f} ({ok}/{runs}) | {int(r['knocks'])} | "
            f"{int(r['timeouts'])} | {r['mean_s']:.1f} |"
        )
    return "\n".join(lines)


def charge(stores: list[Path]) -> str:
    """Per condition, mean seconds per run with the robot in charge (``alpha > 0``) toward a
    wrong object and toward the target, and with a wrong object predicted (from the samples)."""
    rows: dict[str, list[tuple[float, float, float]]] = {}
    for db in stores:
        tables = load_tables(db=db)
        t = tables.trials
        t = t[(t["phase"] == "task") & (t["status"] == "completed")]
        s = tables.samples
        if s is None or s.empty:
            continue
        for trial in t.itertuples():
            mine = s[s["trial_id"] == trial.trial_id]
            dt = float(np.median(np.diff(mine["t"]))) if len(mine) > 1 else 0.0
            wrong = mine["predicted"].astype(str).to_numpy() != str(trial.target)
            on = mine["alpha"].to_numpy() > 0
            rows.setdefault(f"{trial.task} {trial.mode}", []).append(
                (float((on & wrong).sum() * dt), float((on & ~wrong).sum() * dt), wrong.sum() * dt)
            )
    lines = [
        "| condition | runs | in charge, wrong object (s) | in charge, target (s) | "
        "wrong object predicted (s) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for cond in sorted(rows):
        v = np.array(rows[cond])
        lines.append(
            f"| {cond} | {len(v)} | {v[:, 0].mean():.2f} | {v[:, 1].mean():.2f} | "
            f"{v[:, 2].mean():.1f} |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("stores", nargs="+", type=Path)
    parser.add_argument("--charge", action="store_true", help="who was in charge, per condition")
    args = parser.parse_args()
    results = [one_store(db) for db in args.stores]
    print(markdown(results))
    if args.charge:
        print()
        print(charge(args.stores))
    print(json.dumps(results, default=lambda o: None if np.isnan(o) else o))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Simulated study against the paper: every reported effect, and how often 8 people find it.

    .venv/bin/python benchmarks/power.py [--seeds 20] [--participants 8] [--workers 2]

For each seed ``1..seeds`` it simulates ``participants`` people through the whole protocol into
a fresh temporary store (the real session engine and control loop) and runs the report's
analyses (``analysis.results.analyse``). For every statistic the paper reports (its
``paper_value``) it prints the median over seeds next to the paper's value and the share of
seeds in which the effect is significant at .05 (Bonferroni-corrected where the report
corrects) *in the paper's direction* -- the power of an 8-person replication on this platform.
It also prints the median decoy share of Wrong trials (``analysis.decoy_share``), the mean
trial time and the outcomes, and, as its last line, one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.decoy_share import decoy_shares  # noqa: E402
from analysis.load import load_tables  # noqa: E402
from analysis.results import analyse  # noqa: E402
from study.simulated.runner import simulate  # noqa: E402

# The paper's direction of each effect, as the sign of our statistic (or of a cell contrast).
# Main effects: hard, wrong, aggressive slower. Post-hoc: aggressive&wrong slower than
# timid&wrong. Planned: aggressive faster on Hard&Right (t < 0 for aggressive - timid), timid
# faster on Easy&Wrong (t > 0). Interaction: aggressive costs more when wrong. Prediction:
# memory-based better, timid easier to predict.
SIGNS: dict[tuple[str, str], float] = {
    ("timing_posthoc", "aggressive&wrong - timid&wrong (aggressive vs timid when wrong)"): 1.0,
    ("timing_planned", "Hard&Right: aggressive - timid"): -1.0,
    ("timing_planned", "Easy&Wrong: aggressive - timid"): 1.0,
}


def _direction(res: Any, analysis: str, effect: str, statistic: float) -> float:
    """+1 when the simulated effect points the paper's way, -1 when against it, 0 unknown."""
    if (analysis, effect) in SIGNS:
        return float(np.sign(statistic) * SIGNS[(analysis, effect)])
    cells = res.cells
    mean = cells.groupby(["difficulty", "correctness", "mode"])["duration_s"].mean()
    if analysis == "timing_ancova" and effect in ("difficulty", "correctness", "mode"):
        hi = {"difficulty": "hard", "correctness": "wrong", "mode": "aggressive"}[effect]
        by = cells.groupby(effect)["duration_s"].mean()
        return float(np.sign(by[hi] - by.drop(hi).mean()))
    if analysis == "timing_ancova" and effect == "correctness:mode":
        m = mean.groupby(["correctness", "mode"]).mean()
        cost = (m["wrong", "aggressive"] - m["wrong", "timid"]) - (
            m["right", "aggressive"] - m["right", "timid"]
        )
        return float(np.sign(cost))
    if analysis == "prediction_anova" and res.evals is not None:
        ev = res.evals
        if effect == "predictor":
            by = ev.groupby("predictor")["success_rate"].mean()
            return float(np.sign(by.get("memory", np.nan) - by.get("amnesic", np.nan)))
        if effect == "mode":
            by = ev.groupby("mode")["success_rate"].mean()
            return float(np.sign(by["timid"] - by["aggressive"]))
    if analysis in ("preference", "timing_effects", "timing_mean"):
        return float(np.sign(statistic))
    return 0.0


def one_seed(seed: int, *, participants: int, workers: int, tmp: Path) -> dict[str, Any]:
    db = tmp / f"power-{seed}.db"
    start = time.perf_counter()
    simulate(
        protocol_path=ROOT / "protocols" / "dragan2013.toml",
        db=db,
        participants=participants,
        seed=seed,
        workers=workers,
        progress=False,
    )
    sim_wall = time.perf_counter() - start
    tables = load_tables(db=db)
    res = analyse(tables)
    stats = res.statistics
    rows = []
    for r in stats[stats["paper_value"].notna()].itertuples(index=False):
        p = r.p_bonf if pd.notna(r.p_bonf) else r.p
        sign = _direction(res, r.analysis, r.effect, float(r.statistic))
        rows.append(
            {
                "analysis": r.analysis,
                "effect": r.effect,
                "statistic": float(r.statistic),
                "df": f"{r.df1:g}, {r.df2:g}"
                if pd.notna(r.df2)
                else (f"{r.df1:g}" if pd.notna(r.df1) else ""),
                "paper": str(r.paper_value),
                "significant": bool(pd.notna(p) and p < 0.05 and sign > 0),
                "tested": bool(pd.notna(p)),
            }
        )
    shares = decoy_shares(tables.trials, tables.samples)
    task = tables.trials[(tables.trials["phase"] == "task")]
    return {
        "seed": seed,
        "rows": rows,
        "decoy_share": float(shares["decoy_share"].median()) if len(shares) else float("nan"),
        "outcomes": dict(Counter(task["outcome"].astype(str))),
        "wall_s": round(sim_wall, 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--participants", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    runs = []
    with tempfile.TemporaryDirectory(prefix="bench-power-") as scratch:
        for seed in range(1, args.seeds + 1):
            runs.append(
                one_seed(
                    seed, participants=args.participants, workers=args.workers, tmp=Path(scratch)
                )
            )
            print(f"seed {seed}: {runs[-1]['wall_s']} s", file=sys.stderr)
    table = pd.DataFrame([dict(r, seed=run["seed"]) for run in runs for r in run["rows"]])
    summary = (
        table.groupby(["analysis", "effect"], sort=False)
        .agg(
            df=("df", "first"),
            simulated_median=("statistic", "median"),
            paper=("paper", "first"),
            significant_share=("significant", "mean"),
            tested=("tested", "any"),
        )
        .reset_index()
    )
    pd.set_option("display.width", 200)
    pd.set_option("display.max_colwidth", 60)
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    outcomes: Counter[str] = Counter()
    for run in runs:
        outcomes.update(run["outcomes"])
    decoy = float(np.nanmedian([run["decoy_share"] for run in runs]))
    print(f"decoy share of Wrong trials (median of seeds' medians): {decoy:.2f}")
    print(f"task trial outcomes over all seeds: {dict(outcomes)}")
    out = {
        "seeds": args.seeds,
        "participants": args.participants,
        "decoy_share": round(decoy, 3),
        "outcomes": dict(outcomes),
        "effects": [
            {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}
            for row in summary.to_dict(orient="records")
        ],
    }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

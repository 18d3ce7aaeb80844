"""``python -m analysis predict``: goal prediction along any trajectory, from CSV files.

GOALS.csv: ``goal,x,y[,z]`` (or ``goal,q1..qn``); TRAJ.csv: ``t,x,y[,z]`` (or ``t,q1..qn``),
the same coordinate columns. Prints CSV: ``t``, ``p_<goal>`` per goal, ``predicted``,
``confidence`` - the probability of the predicted goal, or with ``--distance-threshold D``
the distance hinge ``max(0, 1 - d / D)`` (d = distance to the predicted goal).
"""

from __future__ import annotations

import argparse
import re
import sys

import numpy as np
import pandas as pd

from analysis.cli import friendly, note
from analysis.cli.anova import read_csv
from analysis.design import numeric_column, require_columns
from analysis.errors import DataError, SchemaError
from analysis.prediction_eval import make_predictor, replay
from study.cli.arguments import float_range

COSTS = {"length": "length", "squared_velocity": "squared_velocity", "sqvel": "squared_velocity"}
"""``--cost`` values: the protocol format's names, plus the short ``sqvel``."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--goals", required=True, help="CSV with columns goal,x,y[,z] or goal,q1..qn"
    )
    parser.add_argument(
        "--trajectory", required=True, help="CSV with columns t,x,y[,z] or t,q1..qn"
    )
    parser.add_argument("--method", required=True, choices=["amnesic", "memory"])
    parser.add_argument(
        "--cost",
        choices=list(COSTS),
        default="squared_velocity",
        help="memory-based cost: path length or sum of squared velocities "
        "(default squared_velocity, as protocols name it and the paper's "
        "offline analysis uses; sqvel for short)",
    )
    parser.add_argument(
        "--temperature",
        type=float_range(0.0, 1e3, above=True),
        default=0.05,
        help="amnesic softmin temperature (distance units)",
    )
    parser.add_argument(
        "--rationality",
        type=float_range(0.0, 1e6, above=True),
        default=1.0,
        help="memory-based rationality b in exp(-b C)",
    )
    parser.add_argument(
        "--distance-threshold",
        type=float_range(0.0, 1e3, above=True),
        default=None,
        metavar="D",
        help="report the distance hinge max(0, 1 - d/D) as confidence",
    )


def coordinate_columns(goals: pd.DataFrame) -> list[str]:
    """``x,y[,z]`` when present, else ``q1..qn`` in order."""
    if {"x", "y"} <= set(goals.columns):
        return ["x", "y"] + (["z"] if "z" in goals.columns else [])
    qs = sorted(
        (c for c in goals.columns if re.fullmatch(r"q\d+", str(c))), key=lambda c: int(c[1:])
    )
    if not qs:
        raise SchemaError(
            "the goals file needs coordinate columns x,y[,z] or q1..qn besides "
            f"'goal'; it has {', '.join(map(str, goals.columns))}"
        )
    if qs != [f"q{i}" for i in range(1, len(qs) + 1)]:
        raise SchemaError(f"configuration columns must be q1..qn without gaps, got {qs}")
    return qs


@friendly
def main(args: argparse.Namespace) -> int:
    goals = read_csv(args.goals)
    traj = read_csv(args.trajectory)
    require_columns(goals, ["goal"], what=args.goals)
    cols = coordinate_columns(goals)
    require_columns(traj, cols, what=args.trajectory)
    names = goals["goal"].astype(str).tolist()
    if len(names) < 2:
        raise DataError(f"{args.goals} lists {len(names)} goal; prediction needs at least two")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(f"goal names must be unique; repeated: {', '.join(dup)}")
    pts = np.column_stack([numeric_column(goals, c, what=args.goals) for c in cols])
    xyz = np.column_stack([numeric_column(traj, c, what=args.trajectory) for c in cols])
    if np.isnan(pts).any():
        raise DataError(f"{args.goals} has empty coordinates; every goal needs {', '.join(cols)}")
    if "t" in traj.columns:
        t = numeric_column(traj, "t", what=args.trajectory).to_numpy()
    else:
        note(f"{args.trajectory} has no 't' column; the row number is used as time")
        t = np.arange(len(traj), dtype=float)
    if args.method == "amnesic":
        cfg = {"kind": "amnesic", "temperature": args.temperature}
    else:
        cfg = {"kind": "memory", "cost": COSTS[args.cost], "rationality": args.rationality}
    rep = replay(pts, xyz, make_predictor(cfg, pts), t=t)
    out = pd.DataFrame({"t": t})
    for k, n in enumerate(names):
        out[f"p_{n}"] = rep.probabilities[:, k]
    out["predicted"] = np.array(names)[rep.predicted]
    if args.distance_threshold is not None:
        if not args.distance_threshold > 0:
            raise DataError("--distance-threshold must be a positive distance")
        d = np.linalg.norm(xyz - pts[rep.predicted], axis=1)
        out["confidence"] = np.clip(1.0 - d / args.distance_threshold, 0.0, 1.0)
    else:
        out["confidence"] = rep.probabilities[np.arange(len(t)), rep.predicted]
    sys.stdout.write(out.to_csv(index=False, float_format="%.6g"))
    return 0

"""The figures a report draws (Figs. 7, 8 and 9), each where the data allow it."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from analysis import figures as figs
from analysis.load import StudyTables
from analysis.prediction_eval import (
    goal_moves,
    make_predictor,
    replay,
    trial_goals,
    trial_trajectories,
)
from analysis.protocol_info import ProtocolInfo
from analysis.ratings import preference_summary, rating_summary
from analysis.study_results import StudyResults


def _example_trial(res: StudyResults) -> Any:
    ev = res.evals
    if ev is None or ev.empty or ev["predictor"].nunique() < 2:
        return None
    w = ev.pivot_table(index="trial_id", columns="predictor", values="success_rate")
    a, b = list(dict.fromkeys(ev["predictor"]))[:2]
    tid = (w[b] - w[a]).idxmax()
    return res.cells[res.cells["trial_id"] == tid].iloc[0]


def _mode_order(res: StudyResults, proto: ProtocolInfo | None) -> tuple[str, ...]:
    if proto is not None and proto.factors.get("mode"):
        return tuple(proto.factors["mode"])
    if res.timing is not None:
        return tuple(res.timing.levels["mode"])
    return ("timid", "aggressive")


def _points(tables: StudyTables) -> int:
    """The rating scale's length: the largest answer seen, at least 7."""
    values = pd.to_numeric(tables.ratings.get("value", pd.Series(dtype=float)), errors="coerce")
    return max(7, int(values.max())) if values.notna().any() else 7


def draw_figures(
    res: StudyResults,
    tables: StudyTables,
    proto: ProtocolInfo | None,
    out: Path,
    predictors: Mapping[str, Mapping[str, Any]],
    *,
    successful_only: bool = False,
) -> dict[str, figs.SavedFigure]:
    made: dict[str, figs.SavedFigure] = {}
    if proto is not None and proto.arbitrations:
        made["fig7"] = figs.save(
            figs.arbitration_figure(proto.arbitrations, rate_hz=proto.rate_hz),
            out,
            "fig7_arbitration",
            "Fig. 7: arbitration α(c) of each mode",
        )
    modes = list(_mode_order(res, proto))
    if not res.cells.empty:
        g = res.cells.groupby(["task", "mode"])["duration_s"]
        time = (g.mean().rename("mean").to_frame().join(g.sem().rename("se"))).reset_index()
        pref, reference = preference_summary(tables)
        runs = "successful runs" if successful_only else "all completed runs"
        made["fig8"] = figs.save(
            figs.timing_preference_figure(
                time,
                pref,
                modes=modes,
                reference=reference,
                time_label=f"time to complete (s), {runs}",
            ),
            out,
            "fig8_time_preference",
            f"Fig. 8: time ({runs}) and preference per task (mean ± SE; no bar without an SE)",
        )
    ratings = rating_summary(tables.ratings, modes=modes)
    if not ratings.empty:
        made["fig8_ratings"] = figs.save(
            figs.ratings_figure(ratings, modes=modes, points=_points(tables)),
            out,
            "fig8_ratings",
            "Fig. 8: ratings per task and mode after each run (mean ± SE)",
        )
    row = _example_trial(res)
    if row is not None and res.evals is not None:
        names, pts, target = trial_goals(row)
        tid = row["trial_id"]
        t, xyz, moved = trial_trajectories(tables.samples[tables.samples["trial_id"] == tid])[tid]
        moves = goal_moves(moved, names, tid)
        reps = {
            name: replay(pts, xyz, make_predictor(cfg, pts), t=t, target=target, moves=moves)
            for name, cfg in list(predictors.items())[:2]
        }
        title = f"trial {row['trial_id']} ({row['participant']}, {row['task']}, {row['mode']})"
        made["fig9"] = figs.save(
            figs.prediction_figure(res.evals, reps, pts, names, target, title, modes=modes),
            out,
            "fig9_prediction",
            "Fig. 9: prediction success (mean ± SE) and one trajectory "
            "(green = correct, red = wrong; arrow = first lasting correct point)",
        )
    return made

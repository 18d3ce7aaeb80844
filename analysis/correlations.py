"""Pearson correlations with df and p: the preference against timing and against the ratings.

``r = cov(x, y) / (sd x sd y)``, ``t = r sqrt(n - 2) / sqrt(1 - r^2)`` on ``n - 2`` df (the
paper's r(30) for 8 participants x 4 tasks); 95% CI by Fisher's z, ``atanh(r) +- 1.96/sqrt(n-3)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import special

from analysis.errors import DesignError, SchemaError
from analysis.load import RATING_ITEMS

COLUMNS = ["measure", "versus", "test", "n", "df", "r", "t", "p", "ci_low", "ci_high"]


def pearson(x: Sequence[float], y: Sequence[float]) -> dict[str, float]:
    """Pearson's r of complete pairs, its t statistic, df = n - 2, two-sided p and 95% CI."""
    x_, y_ = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    keep = ~(np.isnan(x_) | np.isnan(y_))
    x_, y_ = x_[keep], y_[keep]
    n = len(x_)
    if n < 3:
        raise DesignError(f"a correlation needs at least 3 complete pairs, got {n}")
    if np.ptp(x_) == 0 or np.ptp(y_) == 0:
        return {
            "n": n,
            "df": float(n - 2),
            "r": np.nan,
            "t": np.nan,
            "p": np.nan,
            "ci_low": np.nan,
            "ci_high": np.nan,
        }
    r = float(np.corrcoef(x_, y_)[0, 1])
    r = max(-1.0, min(1.0, r))
    df = n - 2
    t = r * np.sqrt(df) / np.sqrt(max(1e-300, 1 - r * r))
    p = float(2 * special.stdtr(df, -abs(t)))
    if n > 3 and abs(r) < 1:
        z, h = np.arctanh(r), 1.959963984540054 / np.sqrt(n - 3)
        lo, hi = float(np.tanh(z - h)), float(np.tanh(z + h))
    else:
        lo = hi = np.nan
    return {"n": n, "df": float(df), "r": r, "t": float(t), "p": p, "ci_low": lo, "ci_high": hi}


def preference_frame(cells: pd.DataFrame) -> pd.DataFrame:
    """One row per participant and task: the preference for the aggressive run (-3..+3), the
    timing advantage of aggressive ``duration(timid) - duration(aggressive)`` in seconds, and
    each rating item's difference ``aggressive - timid``."""
    if "preference_aggressive" not in cells.columns:
        raise SchemaError(
            "the trials table has no 'preference_aggressive' column; the "
            "preference analysis needs it (-3..+3, positive = aggressive preferred)"
        )
    keys = ["participant", "task", "difficulty", "correctness"]
    wide = cells.pivot_table(index=keys, columns="mode", values="duration_s", aggfunc="mean")
    if set(wide.columns) != {"timid", "aggressive"}:
        raise DesignError(
            "the preference analysis compares a timid and an aggressive run per "
            f"task; modes present: {sorted(map(str, wide.columns))}"
        )
    out = pd.DataFrame(
        {
            "duration_timid": wide["timid"],
            "duration_aggressive": wide["aggressive"],
        }
    )
    out["time_advantage_aggressive"] = out["duration_timid"] - out["duration_aggressive"]
    out["preference_aggressive"] = cells.groupby(keys)["preference_aggressive"].mean()
    for item in RATING_ITEMS:
        if item in cells.columns:
            r = cells.pivot_table(index=keys, columns="mode", values=item, aggfunc="mean")
            if {"timid", "aggressive"} <= set(r.columns):
                out[f"{item}_diff"] = r["aggressive"] - r["timid"]
    return out.reset_index().dropna(subset=["time_advantage_aggressive"])


def preference_correlations(cells: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Correlations of the preference with the timing advantage and with each rating item.

    Returns the table of correlations and the per participant-task frame they come from.
    """
    frame = preference_frame(cells)
    rows = [
        {
            "measure": "preference_aggressive",
            "versus": "time_advantage_aggressive",
            "test": "Pearson r",
            **pearson(frame["preference_aggressive"], frame["time_advantage_aggressive"]),
        }
    ]
    for item in RATING_ITEMS:
        col = f"{item}_diff"
        if col in frame.columns:
            rows.append(
                {
                    "measure": col,
                    "versus": "preference_aggressive",
                    "test": "Pearson r",
                    **pearson(frame[col], frame["preference_aggressive"]),
                }
            )
    return pd.DataFrame(rows, columns=COLUMNS), frame

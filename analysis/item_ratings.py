"""Ratings by condition for every Likert item the protocol asks after a run.

Each completed task run carries its answers in the trials table (one column per item, the
export's ``<item>``). Per item and condition (every between group x within condition): ``n``
answers, ``mean``, ``sd`` (n - 1), ``median`` and ``se = sd / sqrt(n)``, over the runs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.factor_design import FactorDesign

COLUMNS = ["item", "condition", "n", "mean", "sd", "median", "se"]


def rated_items(
    cells: pd.DataFrame, ratings: pd.DataFrame, declared: Sequence[str] = ()
) -> tuple[str, ...]:
    """The items to summarise: the protocol's after-run items (``declared``), else those the
    ratings table has after task runs; only those with a column in ``cells``."""
    items = list(declared)
    if not items and {"phase", "mode", "item"} <= set(ratings.columns):
        mode = ratings["mode"].astype("string").fillna("")
        items = list(
            dict.fromkeys(ratings.loc[(ratings["phase"] == "task") & (mode != ""), "item"])
        )
    return tuple(str(i) for i in items if i in cells.columns)


def ratings_by_condition(
    cells: pd.DataFrame, items: Sequence[str], design: FactorDesign
) -> pd.DataFrame:
    """``COLUMNS`` plus one column per factor: each item's answers summarised per condition."""
    factors = list(design.factors)
    rows = []
    for item in items:
        values = pd.to_numeric(cells[item], errors="coerce")
        frame = cells[factors].assign(_v=values)
        for key, g in frame.groupby(factors, observed=True, sort=True):
            levels = dict(zip(factors, map(str, np.atleast_1d(key)), strict=True))
            v = g["_v"].dropna()
            n = len(v)
            sd = float(v.std(ddof=1)) if n > 1 else np.nan
            rows.append(
                {
                    "item": item,
                    "condition": design.label(levels),
                    **levels,
                    "n": n,
                    "mean": float(v.mean()) if n else np.nan,
                    "sd": sd,
                    "median": float(v.median()) if n else np.nan,
                    "se": sd / np.sqrt(n) if n > 1 else np.nan,
                }
            )
    return pd.DataFrame(rows, columns=[*COLUMNS[:2], *factors, *COLUMNS[2:]])

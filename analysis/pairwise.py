"""Post-hoc comparisons by factor name: every pair of conditions and every pair of a factor's
levels, with Bonferroni and Holm corrections within each family.

Families (``m`` = the number of pairs in the family):

- ``conditions``: every pair of cells (between group x within condition) on the participants'
  cell means: paired t (``d_z``) when both cells are of one group, Welch's t (``d``) otherwise.
- ``<factor> levels``: every pair of the factor's levels on each participant's marginal mean
  (averaged over the other within factors): paired t for a within factor, Welch's t between
  the groups for a between factor.

``p_bonf = min(1, m p)`` with the Bonferroni CI ``diff +- t_{1 - .025/m, df} se``;
``p_holm`` is Holm's step-down (:mod:`analysis.multiplicity`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import special

from analysis.multiplicity import bonferroni, holm
from analysis.posthoc import paired_t
from analysis.split_plot import SplitPlotResult
from analysis.welch import welch_t

COLUMNS = [
    "family",
    "comparison",
    "test",
    "n",
    "df",
    "t",
    "p",
    "m",
    "p_bonf",
    "p_holm",
    "mean_a",
    "mean_b",
    "mean_diff",
    "ci_low",
    "ci_high",
    "ci_low_bonf",
    "ci_high_bonf",
    "effect_size",
    "effect_size_name",
]
CONDITIONS = "conditions"


def _label(names: Sequence[str], levels: Sequence[str]) -> str:
    return ", ".join(f"{f}={v}" for f, v in zip(names, levels, strict=True))


def _test(a: np.ndarray, b: np.ndarray, *, paired: bool) -> dict[str, float | str]:
    if paired:
        r = paired_t(a, b)
        return {**r, "test": "paired t", "effect_size": r.pop("d_z"), "effect_size_name": "d_z"}
    r = welch_t(a, b)
    return {**r, "test": "Welch t", "effect_size": r.pop("d"), "effect_size_name": "d"}


def _groups(fit: SplitPlotResult) -> tuple[list[tuple[str, ...]], np.ndarray]:
    """The between groups (level tuples, observed order) and each subject's group index."""
    if not fit.between:
        return [()], np.zeros(fit.n_subjects, dtype=int)
    keys = [tuple(map(str, r)) for r in fit.groups[list(fit.between)].itertuples(index=False)]
    order = list(dict.fromkeys(sorted(keys, key=lambda k: _level_rank(fit, k))))
    return order, np.array([order.index(k) for k in keys])


def _level_rank(fit: SplitPlotResult, key: tuple[str, ...]) -> tuple[int, ...]:
    return tuple(
        list(fit.groups[f].cat.categories).index(v) for f, v in zip(fit.between, key, strict=True)
    )


def _condition_pairs(fit: SplitPlotResult) -> list[dict[str, float | str]]:
    cells = fit.cells
    groups, member = _groups(fit)
    units = [(g, c) for g in range(len(groups)) for c in range(len(cells.cells))]
    rows = []
    for (g1, c1), (g2, c2) in itertools.combinations(units, 2):
        a = cells.values[member == g1, c1]
        b = cells.values[member == g2, c2]
        names = [*fit.between, *cells.factors]
        la = _label(names, [*groups[g1], *cells.cells[c1]])
        lb = _label(names, [*groups[g2], *cells.cells[c2]])
        rows.append(
            {"family": CONDITIONS, "comparison": f"{la} - {lb}", **_test(a, b, paired=g1 == g2)}
        )
    return rows


def _within_level_pairs(fit: SplitPlotResult) -> list[dict[str, float | str]]:
    cells = fit.cells
    cube = cells.values.reshape(len(cells.subjects), *[len(lv) for lv in cells.levels])
    rows = []
    for i, f in enumerate(cells.factors):
        others = tuple(j + 1 for j in range(len(cells.factors)) if j != i)
        margin = cube.mean(axis=others) if others else cube
        for j, k in itertools.combinations(range(len(cells.levels[i])), 2):
            rows.append(
                {
                    "family": f"{f} levels",
                    "comparison": f"{cells.levels[i][j]} - {cells.levels[i][k]}",
                    **_test(margin[:, j], margin[:, k], paired=True),
                }
            )
    return rows


def _between_level_pairs(fit: SplitPlotResult) -> list[dict[str, float | str]]:
    means = fit.cells.values.mean(axis=1)
    rows = []
    for f in fit.between:
        col = fit.groups[f]
        present = [str(v) for v in col.cat.categories if (col == v).any()]
        for a, b in itertools.combinations(present, 2):
            rows.append(
                {
                    "family": f"{f} levels",
                    "comparison": f"{a} - {b}",
                    **_test(
                        means[(col == a).to_numpy()], means[(col == b).to_numpy()], paired=False
                    ),
                }
            )
    return rows


def _corrected(out: pd.DataFrame) -> pd.DataFrame:
    """``m``, ``p_bonf``, ``p_holm`` and the Bonferroni CI within each family."""
    out["m"] = out.groupby("family", sort=False)["family"].transform("size").astype(int)
    out["p_bonf"] = np.nan
    out["p_holm"] = np.nan
    for _, idx in out.groupby("family", sort=False).groups.items():
        p = out.loc[idx, "p"].to_numpy(dtype=float)
        out.loc[idx, "p_bonf"] = bonferroni(p)
        out.loc[idx, "p_holm"] = holm(p)
    df = out["df"].to_numpy(dtype=float)
    widen = special.stdtrit(df, 1 - 0.025 / out["m"].to_numpy()) / special.stdtrit(df, 0.975)
    half = (out["ci_high"] - out["ci_low"]).to_numpy() / 2 * widen
    out["ci_low_bonf"] = out["mean_diff"] - half
    out["ci_high_bonf"] = out["mean_diff"] + half
    return out


def pairwise_comparisons(fit: SplitPlotResult) -> pd.DataFrame:
    """Every pair of conditions and of each factor's levels (``COLUMNS``; module docstring)."""
    rows = [*_condition_pairs(fit), *_between_level_pairs(fit), *_within_level_pairs(fit)]
    out = pd.DataFrame(rows)
    if out.empty:
        return pd.DataFrame(columns=COLUMNS)
    return _corrected(out)[COLUMNS]

"""Paired comparisons: t-tests with Bonferroni correction, Cohen's d_z and 95% confidence intervals.

For pairs ``(a_i, b_i)`` with differences ``d_i = a_i - b_i``:
``t = mean(d) / (sd(d) / sqrt(n))`` on ``n - 1`` df, ``d_z = mean(d) / sd(d)``, the 95% CI of
``mean(d)`` is ``mean(d) +- t_{.975, n-1} sd(d) / sqrt(n)`` (not adjusted), and within a family
of ``m`` comparisons ``p_bonf = min(1, m p)`` with the matching Bonferroni CI
``mean(d) +- t_{1 - .025/m, n-1} sd(d) / sqrt(n)`` (it excludes 0 exactly when ``p_bonf < .05``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import special

from analysis.errors import DesignError

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
    "mean_a",
    "mean_b",
    "mean_diff",
    "ci_low",
    "ci_high",
    "ci_low_bonf",
    "ci_high_bonf",
    "d_z",
]


@dataclass(frozen=True)
class Comparison:
    """One planned or post-hoc comparison: ``a - b`` over matched pairs."""

    family: str
    label: str
    a: np.ndarray
    b: np.ndarray


def paired_t(a: Sequence[float], b: Sequence[float]) -> dict[str, float]:
    """Paired t-test of ``a - b`` with effect size ``d_z`` and the 95% CI of the mean difference."""
    a_, b_ = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a_.shape != b_.shape or a_.ndim != 1:
        raise DesignError(
            f"paired samples must be two 1-D arrays of equal length, got shapes "
            f"{a_.shape} and {b_.shape}"
        )
    keep = ~(np.isnan(a_) | np.isnan(b_))
    a_, b_ = a_[keep], b_[keep]
    n = len(a_)
    if n < 2:
        raise DesignError(f"a paired t-test needs at least 2 complete pairs, got {n}")
    d = a_ - b_
    mean, sd = float(d.mean()), float(d.std(ddof=1))
    se = sd / np.sqrt(n)
    t = mean / se if se > 0 else (np.inf * np.sign(mean) if mean else np.nan)
    p = float(2 * special.stdtr(n - 1, -abs(t))) if np.isfinite(t) else (0.0 if mean else 1.0)
    half = float(special.stdtrit(n - 1, 0.975) * se)
    return {
        "n": n,
        "df": float(n - 1),
        "t": float(t),
        "p": p,
        "mean_a": float(a_.mean()),
        "mean_b": float(b_.mean()),
        "mean_diff": mean,
        "ci_low": mean - half,
        "ci_high": mean + half,
        "d_z": mean / sd if sd > 0 else np.nan,
    }


def paired_comparisons(comparisons: Sequence[Comparison]) -> pd.DataFrame:
    """Run every comparison; Bonferroni-correct within each family (``m`` = family size)."""
    rows = [
        {"family": c.family, "comparison": c.label, "test": "paired t", **paired_t(c.a, c.b)}
        for c in comparisons
    ]
    out = pd.DataFrame(
        rows,
        columns=[c for c in COLUMNS if c not in ("m", "p_bonf", "ci_low_bonf", "ci_high_bonf")],
    )
    sizes = out.groupby("family")["family"].transform("size")
    out.insert(out.columns.get_loc("p") + 1, "m", sizes.astype(int))
    out.insert(out.columns.get_loc("m") + 1, "p_bonf", np.minimum(1.0, out["p"] * out["m"]))
    df = out["df"].to_numpy(dtype=float)
    widen = special.stdtrit(df, 1 - 0.025 / out["m"].to_numpy()) / special.stdtrit(df, 0.975)
    half = (out["ci_high"] - out["ci_low"]).to_numpy() / 2 * widen
    out["ci_low_bonf"] = out["mean_diff"] - half
    out["ci_high_bonf"] = out["mean_diff"] + half
    return out[COLUMNS]

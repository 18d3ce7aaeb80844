"""Welch's two-sample t-test (unequal variances): participants of two between-subject groups.

``t = (mean_a - mean_b) / sqrt(v_a / n_a + v_b / n_b)`` on the Welch-Satterthwaite df
``(v_a/n_a + v_b/n_b)^2 / ((v_a/n_a)^2 / (n_a - 1) + (v_b/n_b)^2 / (n_b - 1))``; Cohen's ``d``
on the pooled SD ``sqrt(((n_a - 1) v_a + (n_b - 1) v_b) / (n_a + n_b - 2))``; the 95% CI of the
difference ``diff +- t_{.975, df} se``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import special

from analysis.errors import DesignError


def welch_t(a: Sequence[float], b: Sequence[float]) -> dict[str, float]:
    """Welch's t of ``mean(a) - mean(b)`` (module docstring); missing values left out."""
    a_ = np.asarray(a, dtype=float)
    b_ = np.asarray(b, dtype=float)
    a_, b_ = a_[~np.isnan(a_)], b_[~np.isnan(b_)]
    na, nb = len(a_), len(b_)
    if na < 2 or nb < 2:
        raise DesignError(
            f"a two-sample t-test needs at least 2 participants per group, got {na} and {nb}"
        )
    va, vb = float(a_.var(ddof=1)), float(b_.var(ddof=1))
    diff = float(a_.mean() - b_.mean())
    sa, sb = va / na, vb / nb
    se = float(np.sqrt(sa + sb))
    den = sa * sa / (na - 1) + sb * sb / (nb - 1)
    df = (sa + sb) ** 2 / den if den > 0 else float(na + nb - 2)
    t = diff / se if se > 0 else (np.inf * np.sign(diff) if diff else np.nan)
    p = float(2 * special.stdtr(df, -abs(t))) if np.isfinite(t) else (0.0 if diff else 1.0)
    half = float(special.stdtrit(df, 0.975) * se)
    pooled = np.sqrt(((na - 1) * va + (nb - 1) * vb) / (na + nb - 2))
    return {
        "n": na + nb,
        "df": float(df),
        "t": float(t),
        "p": p,
        "mean_a": float(a_.mean()),
        "mean_b": float(b_.mean()),
        "mean_diff": diff,
        "ci_low": diff - half,
        "ci_high": diff + half,
        "d": diff / pooled if pooled > 0 else np.nan,
    }

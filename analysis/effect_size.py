"""Partial eta squared of an F test and its confidence interval by noncentral-F inversion.

``np2 = F df1 / (F df1 + df2)``. The CI inverts the noncentral F (Steiger 2004): the bounds of
the noncentrality ``lambda`` solve ``P(F' <= F_obs; df1, df2, lambda) = 1 - a/2`` and ``= a/2``,
and ``np2 = lambda / (lambda + df1 + df2 + 1)`` maps them to the eta scale (exact for fixed-effects
ANOVA; an approximation for repeated-measures and mixed-model F tests, as usually reported).
"""

from __future__ import annotations

import math

from scipy import optimize, stats


def partial_eta_squared(f: float, df1: float, df2: float) -> float:
    """``F df1 / (F df1 + df2)``: the share of effect plus error variance due to the effect."""
    if not all(math.isfinite(v) for v in (f, df1, df2)) or df2 <= 0:
        return float("nan")
    return f * df1 / (f * df1 + df2)


LAMBDA_MAX = 1e9
"""The largest noncentrality searched: beyond it the CI's bound is reported as not computable
(NaN; the F is then astronomically large: an effect without error variance)."""


def _lambda_bound(f: float, df1: float, df2: float, prob: float) -> float:
    """The noncentrality at which ``P(F' <= f) = prob`` (0 when even lambda = 0 falls short)."""

    def gap(lam: float) -> float:
        return (
            float(stats.ncf.cdf(f, df1, df2, lam) - prob)
            if lam > 0
            else float(stats.f.cdf(f, df1, df2) - prob)
        )

    if gap(0.0) <= 0:
        return 0.0
    hi = max(10.0, 4 * f * df1)
    while hi <= LAMBDA_MAX:
        above = gap(hi)
        if not math.isfinite(above):  # scipy's noncentral F gives up before LAMBDA_MAX
            break
        if above <= 0:
            return float(optimize.brentq(gap, 0.0, hi, xtol=1e-10))
        hi *= 2
    return float("nan")  # an F so large (an effect without error) that the bound is lost


def np2_ci(f: float, df1: float, df2: float, *, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` CI of partial eta squared (see the module docstring)."""
    if not all(math.isfinite(v) for v in (f, df1, df2)) or f < 0 or df2 <= 0:
        return float("nan"), float("nan")
    a = 1 - level
    lo = _lambda_bound(f, df1, df2, 1 - a / 2)
    hi = _lambda_bound(f, df1, df2, a / 2)
    scale = df1 + df2 + 1
    return lo / (lo + scale), hi / (hi + scale)

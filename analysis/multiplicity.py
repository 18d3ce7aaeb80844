"""Corrections for a family of ``m`` tests: Bonferroni and Holm's step-down.

Bonferroni: ``p_bonf,i = min(1, m p_i)``. Holm (1979): with the p values sorted ascending,
``p_holm,(j) = max_{i <= j} min(1, (m - i + 1) p_(i))`` -- the same family-wise error rate as
Bonferroni, never larger than it, and more powerful. A missing p (NaN) stays missing and does
not count towards ``m``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def bonferroni(p: Sequence[float] | np.ndarray) -> np.ndarray:
    """Bonferroni-adjusted p values of one family (module docstring)."""
    p_ = np.asarray(p, dtype=float)
    m = int(np.sum(~np.isnan(p_)))
    return np.minimum(1.0, p_ * m)


def holm(p: Sequence[float] | np.ndarray) -> np.ndarray:
    """Holm-adjusted p values of one family, in the input order (module docstring)."""
    p_ = np.asarray(p, dtype=float)
    out = np.full(p_.shape, np.nan)
    ok = np.flatnonzero(~np.isnan(p_))
    m = len(ok)
    if not m:
        return out
    order = ok[np.argsort(p_[ok], kind="stable")]
    steps = np.minimum(1.0, (m - np.arange(m)) * p_[order])
    out[order] = np.maximum.accumulate(steps)
    return out

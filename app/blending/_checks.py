"""Argument checks shared by the modules (construction time; the per-tick path stays lean)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import InvalidInputError


def as_finite_array(value: Any, *, name: str, ndim: int, dim: int | None = None) -> np.ndarray:
    """``value`` as a float64 array of ``ndim`` dimensions, every entry finite.

    ``dim`` (if given) is the required size of the last axis.
    """
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name}: expected numbers, got {value!r} ({exc})") from None
    if arr.ndim != ndim:
        raise InvalidInputError(f"{name}: expected a {ndim}-D array, got shape {arr.shape}")
    if dim is not None and arr.shape[-1] != dim:
        raise InvalidInputError(f"{name}: expected last dimension {dim}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise InvalidInputError(f"{name}: contains NaN or infinite values: {arr!r}")
    return arr


def as_point(value: Any, *, name: str, dim: int | None = None) -> np.ndarray:
    """A finite 1-D vector (of length ``dim`` if given)."""
    return as_finite_array(value, name=name, ndim=1, dim=dim)


def as_points(value: Any, *, name: str, dim: int | None = None) -> np.ndarray:
    """A finite, non-empty ``(n, d)`` array of points."""
    arr = as_finite_array(value, name=name, ndim=2, dim=dim)
    if arr.shape[0] == 0:
        raise InvalidInputError(f"{name}: the goal set is empty; give at least one goal")
    if arr.shape[1] == 0:
        raise InvalidInputError(f"{name}: points have zero dimensions")
    return arr


def positive(value: Any, *, name: str, allow_zero: bool = False) -> float:
    """A finite float > 0 (or >= 0 with ``allow_zero``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InvalidInputError(f"{name}: must be finite and {bound}, got {value!r}")
    return v


def in_interval(
    value: Any, *, name: str, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False
) -> float:
    """A finite float in the interval from ``lo`` to ``hi`` (open or closed at either end)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}")
    v = float(value)
    ok = math.isfinite(v)
    ok = ok and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise InvalidInputError(f"{name}: must be in {interval}, got {value!r}")
    return v


def probability_vector(value: Any, *, name: str, n: int) -> np.ndarray:
    """A prior: ``n`` non-negative finite weights with a positive sum, normalised to sum 1."""
    arr = as_finite_array(value, name=name, ndim=1, dim=n)
    if (arr < 0).any() or arr.sum() <= 0:
        raise InvalidInputError(
            f"{name}: weights must be >= 0 with a positive sum, got {arr.tolist()}"
        )
    return arr / arr.sum()

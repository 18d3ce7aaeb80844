"""The interface's reach: the box of end-effector targets a participant can point at."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.teleop.errors import InvalidTargetError, TeleopError


def finite3(v: np.ndarray) -> bool:
    """``v`` is a (3,) float array of finite numbers (a tenth of ``np.all(np.isfinite(v))``'s
    cost: checked on every control tick's target)."""
    if v.shape != (3,):
        return False
    x, y, z = v.tolist()
    return math.isfinite(x) and math.isfinite(y) and math.isfinite(z)


@dataclass(frozen=True)
class ReachRegion:
    """Axis-aligned box ``lo <= x <= hi`` (world frame, metres) the user's target is clamped to.

    Hard scenes put the target object just outside it: the user alone cannot get there.
    """

    lo: np.ndarray
    hi: np.ndarray

    def __post_init__(self) -> None:
        lo = np.asarray(self.lo, dtype=float).reshape(-1)
        hi = np.asarray(self.hi, dtype=float).reshape(-1)
        if lo.shape != (3,) or hi.shape != (3,):
            raise TeleopError(
                f"ReachRegion: lo and hi must be 3-vectors, got {lo.shape}, {hi.shape}"
            )
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
            raise TeleopError(f"ReachRegion: need finite lo < hi on every axis, got {lo}, {hi}")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    def contains(self, x: np.ndarray, *, tol: float = 1e-9) -> bool:
        x = np.asarray(x, dtype=float)
        return bool(np.all(x >= self.lo - tol) and np.all(x <= self.hi + tol))

    def clamp(self, x: np.ndarray) -> np.ndarray:
        """``min(max(x, lo), hi)`` per axis; a non-finite target raises ``InvalidTargetError``."""
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.shape != (3,):
            raise InvalidTargetError(f"target must be a 3-vector (x, y, z), got shape {x.shape}")
        if not finite3(x):
            raise InvalidTargetError(f"target must be finite, got {x.tolist()}")
        return np.minimum(np.maximum(x, self.lo), self.hi)

    def distance_outside(self, x: np.ndarray) -> float:
        """Euclidean distance from ``x`` to the box (0 inside)."""
        x = np.asarray(x, dtype=float)
        return float(np.linalg.norm(x - np.minimum(np.maximum(x, self.lo), self.hi)))

"""Amnesic prediction: only the current input counts.

``G* = argmin_G d(x, G)`` with ``d`` a distance metric (Euclidean by default; pass workspace
points for ``||phi(U) - phi(G)||`` or configurations for ``||U - G||``). So that every
confidence measure applies, the distances become probabilities by a softmin with temperature
``T``: ``P(G | x) = exp(-d(x, G) / T) / sum_G' exp(-d(x, G') / T)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .._checks import as_points, positive
from ..errors import InvalidInputError
from .base import GoalPoints, GoalPrediction, check_x, softmax

__all__ = ["AmnesicPredictor", "Metric", "euclidean"]

Metric = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``metric(x: (d,), points: (n, d)) -> (n,)`` non-negative distances."""


def euclidean(x: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``||x - G||`` for every row ``G`` of ``points``."""
    d = points - x
    d *= d
    s = np.add.reduce(d, axis=1)  # d.sum(axis=1) without its Python wrapper (per tick)
    return np.sqrt(s, out=s)


class AmnesicPredictor(GoalPoints):
    """Softmin of the distance from the current input to each goal.

    Args:
        points: ``(n, d)`` goals in the predictor's space.
        temperature: ``T > 0``; smaller is sharper (``T -> 0`` is the hard argmin).
        metric: distance ``(x, points) -> (n,)``; Euclidean by default.
        space: label of the predictor's space (``"workspace"``/``"configuration"``), informative.
    """

    def __init__(
        self,
        points: Any,
        *,
        temperature: float = 0.05,
        metric: Metric | None = None,
        space: str | None = None,
    ) -> None:
        self.temperature = positive(temperature, name="temperature")
        self.metric: Metric = metric if metric is not None else euclidean
        self.space = space
        self.set_points(points)

    def set_points(self, points: Any) -> None:
        """Replace the goals (any number, any place); the dimension may not change once reset."""
        pts = as_points(points, name="points")
        if getattr(self, "points", None) is not None and pts.shape[1] != self.dim:
            raise InvalidInputError(f"points: dimension changed from {self.dim} to {pts.shape[1]}")
        self.points = pts
        self._neg_inv_t = -1.0 / self.temperature
        # the per-tick fast path's copy of 3-D points (see _update)
        self._rows = (pts, pts.tolist()) if pts.shape[1] == 3 else None

    def reset(self, start: Any) -> None:
        """Amnesic prediction keeps no history; only checks ``start``."""
        check_x(start, self.dim, "start")

    def update(self, x: Any) -> GoalPrediction:
        return self._update(check_x(x, self.dim))

    def _update(self, x: np.ndarray) -> GoalPrediction:
        rows = self._rows
        if self.metric is euclidean and rows is not None and rows[0] is self.points:
            # fast path, 3-D Euclidean: the same numbers as euclidean() (the same operations in
            # the same order), in scalars instead of four array operations
            px, py, pz = x.tolist()
            s = self._neg_inv_t
            logits = []
            for gx, gy, gz in rows[1]:
                dx, dy, dz = gx - px, gy - py, gz - pz
                logits.append(math.sqrt(dx * dx + dy * dy + dz * dz) * s)
            return softmax(np.array(logits))
        d = np.asarray(self.metric(x, self.points), dtype=np.float64)
        if d.shape != (self.points.shape[0],):
            raise InvalidInputError(
                f"metric: returned shape {d.shape}, expected ({self.points.shape[0]},)"
            )
        d *= self._neg_inv_t
        return softmax(d)

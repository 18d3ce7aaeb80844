"""General Laplace form of memory-based prediction, eq. 8 of the paper.

Approximating ``∫ exp(-C(xi_{X->Y}))`` by Laplace's method (eq. 5-7) gives
``exp(-C(xi*_{X->Y})) sqrt((2 pi)^k) / sqrt(|H_{X->Y}|)``, so

``P(G | xi_{S->U}) ∝ exp(-C(xi_{S->U}) - C(xi*_{U->G})) / exp(-C(xi*_{S->G}))
                     * sqrt(|H_{S->G}|) / sqrt(|H_{U->G}|) * P(G)``

which is eq. 9 times the Hessian factor. When the Hessian is constant (a quadratic cost) the
factor is the same for every goal and cancels: eq. 8 reduces to eq. 9. With rationality ``b``
the Hessians become ``b H``; the extra ``b^k`` is shared by all goals and cancels too.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InvalidInputError
from .costs import HessianCost
from .memory import MemoryPredictor

__all__ = ["LaplacePredictor"]


class LaplacePredictor(MemoryPredictor):
    """Eq. 8 for a cost that supplies ``log_det_hessian(x, points) -> (n,)``.

    Args: as :class:`MemoryPredictor`, with ``cost`` a :class:`HessianCost`.
    """

    def __init__(
        self,
        points: Any,
        *,
        cost: HessianCost,
        rationality: float = 1.0,
        prior: Any | None = None,
        space: str | None = None,
    ) -> None:
        if not isinstance(cost, HessianCost):
            raise InvalidInputError(
                f"cost: eq. 8 needs a cost with log_det_hessian(x, points), got {cost!r}"
            )
        super().__init__(points, cost=cost, rationality=rationality, prior=prior, space=space)

    def _hessian_term(self, x: np.ndarray) -> np.ndarray:
        h = np.asarray(self.cost.log_det_hessian(x, self.points), dtype=np.float64)
        if h.shape != (self.n_goals,) or not np.isfinite(h).all():
            raise InvalidInputError(
                f"cost.log_det_hessian: expected {self.n_goals} finite values, got {h!r}"
            )
        return h

    def set_points(self, points: Any, *, prior: Any | None = None) -> None:
        super().set_points(points, prior=prior)
        if self._start is not None:
            self._h_sg = self._hessian_term(self._start)

    def reset(self, start: Any) -> None:
        super().reset(start)
        self._h_sg = self._hessian_term(self._start)

    def _logits(self, x: np.ndarray, c_su: float) -> np.ndarray:
        z = super()._logits(x, c_su)
        z += 0.5 * (self._h_sg - self._hessian_term(x))
        return z

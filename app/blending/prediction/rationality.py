"""Online estimate of the user's rationality ``b`` toward each goal, from their recent motion.

Eq. 9 models the user as noisily optimal, ``P(xi | G) ∝ exp(-b C(xi))``, with ``b`` fixed. Later
work from the same lab (Fisac et al. 2018, "Probabilistically safe robot planning with
confidence-based human predictions"; Bajcsy et al. 2018) estimates this rationality online and
reads a low value as "the model does not explain the person now". Here, for the path-length
cost ``C = ||dx||``: a small step ``dx`` from ``x`` toward goal ``G`` changes the cost-to-go by
``-|dx| cos(theta)`` (``theta`` between ``dx`` and ``G - x``), so under the MaxEnt model the
step's direction is von Mises-Fisher distributed with concentration ``kappa = b |dx|``:

    p(dx_hat | G, b) = kappa / (4 pi sinh kappa) exp(kappa cos theta).

The user's input is read in chunks of at least ``min_step_m`` (so jitter and the tick rate do
not matter). Over a log-spaced grid ``b_k`` (uniform prior on the grid) each goal keeps a
log-likelihood with exponential forgetting over the last ``memory_m`` metres of motion,

    L_{G,k} <- exp(-|dx| / memory_m) L_{G,k} + log p(dx_hat | G, b_k),

(the sphere's normaliser: exact for 3-D inputs, an approximation in other dimensions),
and the estimate is the posterior geometric mean ``b_G = exp(sum_k w_{G,k} log b_k)``,
``w_{G,k} ∝ exp(L_{G,k})``. Motion straight at ``G`` drives ``b_G`` to the top of the grid,
motion across or away from it to the bottom; a user who stands still keeps their estimate.
``direction`` is the unit vector of the latest chunk (``None`` before the user has moved): the
user's actual motion, for the agreement signal of Fig. 15.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._checks import positive
from ..errors import InvalidInputError

__all__ = ["RationalityEstimator"]

GRID = np.geomspace(0.5, 256.0, 10)
"""The rationalities considered, 1/m (``kappa`` from 0.005 to 2.6 per centimetre moved)."""


class RationalityEstimator:
    """``update(x, points) -> b`` per goal (1/m); see the module docstring.

    Args:
        memory_m: metres of recent motion the estimate mostly rests on (forgetting scale).
        min_step_m: the input must move this far before a step counts as evidence.
    """

    def __init__(self, *, memory_m: float = 0.1, min_step_m: float = 0.01) -> None:
        self.memory_m = positive(memory_m, name="memory_m")
        self.min_step_m = positive(min_step_m, name="min_step_m")
        self._min_step2 = self.min_step_m**2
        self._clearly_short = self.min_step_m * (1.0 - 1e-9)  # far beyond rounding's few ulps
        self._log_b = np.log(GRID)
        self._anchor: np.ndarray | None = None
        self._anchor_list: list[float] = []
        self._loglik = np.zeros((0, GRID.size))
        self.estimate = np.zeros(0)
        self.direction: np.ndarray | None = None

    def reset(self, start: Any) -> None:
        """Forget the past; the next evidence is motion away from ``start``."""
        self._anchor = np.array(start, dtype=np.float64)
        self._anchor_list = self._anchor.tolist()
        self._loglik = np.zeros((0, GRID.size))
        self.estimate = np.zeros(0)
        self.direction = None

    def update(self, x: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Take the user's input ``x`` this tick and the goal ``points`` ``(n, d)``; return the
        estimate per goal (the prior's, ``sqrt(0.5 * 256) = 11.3``, before any motion)."""
        anchor = self._anchor
        if anchor is None:
            raise InvalidInputError("reset(start) must be called before update(x)")
        if self._loglik.shape[0] != points.shape[0]:  # the goals changed in number: start over
            self._loglik = np.zeros((points.shape[0], GRID.size))
            self.estimate = self._estimate()
        # a step clearly shorter than min_step_m, told in scalars (most ticks); a step near it
        # is told as before, by the dot product, so the same steps count as evidence
        if math.dist(x.tolist(), self._anchor_list) < self._clearly_short:
            return self.estimate
        step = x - anchor
        ss = float(step.dot(step))
        if ss < self._min_step2:
            return self.estimate
        s = math.sqrt(ss)
        to_goal = points - anchor
        # cos(theta) per goal; a goal exactly at the anchor gives 0 (no information)
        cos = to_goal @ step
        cos /= np.maximum(np.sqrt(np.einsum("ij,ij->i", to_goal, to_goal)), 1e-12) * s
        kappa = GRID * s
        loglik = self._loglik
        loglik *= math.exp(-s / self.memory_m)
        loglik += np.log(kappa) - kappa - np.log1p(-np.exp(-2.0 * kappa))
        loglik += np.multiply.outer(cos, kappa)
        self._anchor = x.copy()
        self._anchor_list = self._anchor.tolist()
        self.direction = step / s
        self.estimate = self._estimate()
        return self.estimate

    def _estimate(self) -> np.ndarray:
        w = self._loglik - self._loglik.max(axis=1, keepdims=True)
        np.exp(w, out=w)
        return np.exp((w @ self._log_b) / w.sum(axis=1))

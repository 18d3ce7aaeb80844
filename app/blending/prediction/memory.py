"""Memory-based goal prediction, eq. 9 of the paper.

``P(G | xi_{S->U}) ∝ exp(-b C(xi_{S->U}) - b C(xi*_{U->G})) / exp(-b C(xi*_{S->G})) P(G)``

with ``b`` the rationality (inverse temperature of the MaxEnt user model
``P(xi | G) ∝ exp(-b C(xi))``), computed in log space. It is incremental: ``C(xi_{S->U})`` is a
running sum and ``C(xi*_{S->G})`` is computed once at ``reset`` (or when the goals change), so a
tick costs ``O(n_goals * dim)`` however long the trajectory is. ``C(xi_{S->U})`` is shared by
all goals and cancels in the normalisation; it is kept for ``log_likelihood`` and clarity.

``rationality="online"`` (path-length cost only) adapts ``b`` to the user: each tick
``b = max_G b_G``, the rationality toward the goal that best explains the user's recent motion
(:class:`~app.blending.prediction.rationality.RationalityEstimator`). A deliberate user
sharpens the prediction; a wandering one flattens it (and so lowers a probability-based
confidence).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._checks import as_points, positive, probability_vector
from ..errors import InvalidInputError
from .base import GoalPoints, GoalPrediction, check_x, softmax
from .costs import Cost, PathLengthCost
from .rationality import GRID, RationalityEstimator

__all__ = ["MemoryPredictor"]


class MemoryPredictor(GoalPoints):
    """Eq. 9 with a pluggable goal-independent cost.

    Args:
        points: ``(n, d)`` goals in the predictor's space.
        cost: :class:`PathLengthCost` (default) or :class:`SquaredVelocityCost` or any ``Cost``.
        rationality: ``b > 0``; larger means the user is modelled as closer to optimal;
            ``"online"`` estimates it from the user's motion (path-length cost only).
        prior: ``(n,)`` non-negative weights ``P(G)`` (normalised); uniform by default.
        space: label of the predictor's space, informative.
    """

    def __init__(
        self,
        points: Any,
        *,
        cost: Cost | None = None,
        rationality: float | str = 1.0,
        prior: Any | None = None,
        space: str | None = None,
    ) -> None:
        self.cost: Cost = cost if cost is not None else PathLengthCost()
        if not isinstance(self.cost, Cost):
            raise InvalidInputError(
                f"cost: needs step(a, b) and to_go(x, points) methods, got {cost!r}"
            )
        self.estimator: RationalityEstimator | None = None
        if rationality == "online":
            if not isinstance(self.cost, PathLengthCost):
                raise InvalidInputError(
                    "rationality: 'online' estimates b for the path-length cost; use cost "
                    "'length' or give a number"
                )
            self.estimator = RationalityEstimator()
            rationality = float(np.exp(np.log(GRID).mean()))  # the estimator's prior
        self.rationality = positive(rationality, name="rationality")
        self.space = space
        self.points: np.ndarray | None = None
        self._start: np.ndarray | None = None
        self.set_points(points, prior=prior)

    @property
    def path_cost(self) -> float:
        """``C(xi_{S->U})`` accumulated so far."""
        return self._c_su

    def set_points(self, points: Any, *, prior: Any | None = None) -> None:
        """Replace the goals (number and place may change) keeping the trajectory so far.

        Eq. 9 needs only S, U and ``C(xi_{S->U})`` besides the goals, so the history survives.
        """
        pts = as_points(points, name="points")
        if self.points is not None and pts.shape[1] != self.dim:
            raise InvalidInputError(f"points: dimension changed from {self.dim} to {pts.shape[1]}")
        n = pts.shape[0]
        if prior is None:
            log_prior = np.full(n, -math.log(n))
        else:
            with np.errstate(divide="ignore"):
                log_prior = np.log(probability_vector(prior, name="prior", n=n))
        self.points = pts
        self.log_prior = log_prior
        if self._start is not None:
            self._c_sg = self.cost.to_go(self._start, pts)

    def reset(self, start: Any) -> None:
        """Begin a trajectory at the user's first input ``S``."""
        s = check_x(start, self.dim, "start").copy()
        self._start = s
        self._prev = s
        self._c_su = 0.0
        self._c_sg = self.cost.to_go(s, self.points)
        if self.estimator is not None:
            self.estimator.reset(s)

    def _require_reset(self) -> None:
        if self._start is None:
            raise InvalidInputError("reset(start) must be called before update(x)")

    def log_likelihood(self, x: np.ndarray) -> np.ndarray:
        """Unnormalised ``log P(G | xi_{S->x})`` per goal (does not advance the trajectory)."""
        self._require_reset()
        x = check_x(x, self.dim)
        c_su = self._c_su + self.cost.step(self._prev, x)
        return self._logits(x, c_su)

    def _logits(self, x: np.ndarray, c_su: float) -> np.ndarray:
        z = self.cost.to_go(x, self.points)
        z += c_su
        z -= self._c_sg
        z *= -self.rationality
        z += self.log_prior
        return z

    def update(self, x: Any) -> GoalPrediction:
        self._require_reset()
        return self._update(check_x(x, self.dim))

    def kernel_inputs(self, x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
        """What a compiled step needs to advance eq. 9 to the input ``x`` as :meth:`update`
        does (``app.blending.assess_core``): ``(C(xi_{S->U}) so far, the last input,
        C(xi*_{S->G}), b)``, ``b`` estimated first when ``"online"``; then
        :meth:`note_update` with the ``C(xi_{S->U})`` it gave."""
        self._require_reset()
        if self.estimator is not None:
            self.rationality = float(self.estimator.update(x, self.points).max())
        return self._c_su, self._prev, self._c_sg, self.rationality

    def note_update(self, x: np.ndarray, c_su: float) -> None:
        """After a compiled step took the input ``x``: ``C(xi_{S->U}) = c_su`` now."""
        self._c_su = c_su
        self._prev = x.copy()

    def _update(self, x: np.ndarray) -> GoalPrediction:
        self._c_su += self.cost.step(self._prev, x)
        self._prev = x.copy()
        if self.estimator is not None:
            self.rationality = float(self.estimator.update(x, self.points).max())
        return softmax(self._logits(x, self._c_su))

"""Goal-independent trajectory costs ``C`` for memory-based prediction (eq. 9) and Laplace (eq. 8).

A cost supplies
    ``step(a, b)``            the cost of one segment, so ``C(xi_{S->U})`` accumulates per tick;
    ``to_go(x, points)``      ``C(xi*_{x->G})``, the optimal cost from ``x`` to each goal;
    ``log_det_hessian(x, points)`` (optional) ``log |H_{x->G}|``, the Hessian of ``C`` at the
                              optimal trajectory from ``x`` to each goal (for eq. 8).
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import InvalidInputError

__all__ = ["Cost", "HessianCost", "PathLengthCost", "SquaredVelocityCost"]


@runtime_checkable
class Cost(Protocol):
    """An additive trajectory cost: ``C(xi) = sum_i step(xi(i-1), xi(i))``."""

    def step(self, a: np.ndarray, b: np.ndarray) -> float: ...

    def to_go(self, x: np.ndarray, points: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class HessianCost(Cost, Protocol):
    """A cost that also gives ``log |H_{x->G}|`` at its optimal trajectories (for eq. 8)."""

    def log_det_hessian(self, x: np.ndarray, points: np.ndarray) -> np.ndarray: ...


class PathLengthCost:
    """Path length: ``C(xi) = sum_i ||xi(i) - xi(i-1)||``; optimum a straight line,
    ``C(xi*_{x->G}) = ||G - x||``.

    With this cost eq. 9 scores each goal by the progress made toward it,
    ``||S - G|| - ||U - G||`` (the C(xi_{S->U}) term is shared by all goals and cancels), which
    gives the paper's null-space effect: goals collinear with S tie while U stays on the segment.
    """

    def step(self, a: np.ndarray, b: np.ndarray) -> float:
        d = b - a
        return math.sqrt(d.dot(d))

    def to_go(self, x: np.ndarray, points: np.ndarray) -> np.ndarray:
        d = points - x
        d *= d
        s = d.sum(axis=1)
        return np.sqrt(s, out=s)

    def __repr__(self) -> str:
        return "PathLengthCost()"


class SquaredVelocityCost:
    """Sum of squared velocities: ``C(xi) = sum_i ||xi(i) - xi(i-1)||^2`` (the paper's offline
    analysis cost).

    The optimal cost-to-go depends on how many steps remain: over ``N`` steps the optimum is
    the straight line in equal steps, ``C(xi*_{x->G}) = ||G - x||^2 / N``. We fix ``N = steps``
    for every completion (a fixed horizon, the same for ``S->G`` and ``U->G``). This is the
    principled choice for eq. 9: the cost is then quadratic in the ``N - 1`` free waypoints with
    the constant Hessian ``2 T_{N-1} (x) I_d`` (``T`` the tridiagonal (2, -1) matrix,
    ``det T_{N-1} = N``), independent of ``x`` and ``G``, which is exactly the case in which
    the paper reduces eq. 8 to eq. 9. (Fixing the step *length* instead would make the number
    of steps ``||G - x|| / l`` and the cost-to-go ``l ||G - x||``: path length again.)
    With this choice eq. 9 scores goals by ``(||S - G||^2 - ||U - G||^2) / N``; ``N`` only
    rescales the rationality.
    """

    def __init__(self, *, steps: int = 1) -> None:
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise InvalidInputError(f"steps: must be an integer >= 1, got {steps!r}")
        self.steps = int(steps)
        self._inv_steps = 1.0 / self.steps

    def step(self, a: np.ndarray, b: np.ndarray) -> float:
        d = b - a
        return float(d.dot(d))

    def to_go(self, x: np.ndarray, points: np.ndarray) -> np.ndarray:
        d = points - x
        d *= d
        s = d.sum(axis=1)
        s *= self._inv_steps
        return s

    def log_det_hessian(self, x: np.ndarray, points: np.ndarray) -> np.ndarray:
        """``log |2 T_{N-1} (x) I_d| = d ((N - 1) log 2 + log N)``, the same for every goal."""
        d = points.shape[1]
        n = self.steps
        value = d * ((n - 1) * math.log(2.0) + math.log(n)) if n > 1 else 0.0
        return np.full(points.shape[0], value)

    def __repr__(self) -> str:
        return f"SquaredVelocityCost(steps={self.steps})"

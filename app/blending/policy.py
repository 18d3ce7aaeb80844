"""Trajectory prediction: the next configuration ``P`` the robot predicts from ``Q`` toward G*.

The study's policy minimises length in configuration space: the straight line from ``Q`` to
the goal configuration, at most ``max_step`` per tick. A workspace variant follows the
straight line of the end effector, mapped to joints through the Jacobian (callables passed in,
so this module imports no kinematics library).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ._checks import positive
from .errors import InvalidInputError

__all__ = ["Policy", "StraightLinePolicy", "WorkspaceLinePolicy"]


@runtime_checkable
class Policy(Protocol):
    """``step(Q, target) -> P``; ``target_space`` says which goal data ``target`` is:
    ``"configuration"`` (goal configuration), ``"workspace"`` (goal position) or ``"goal"``
    (the goal's index; the policy then has ``set_goals(goals)``, which the blender calls with
    every new goal set: :class:`app.blending.policy_grasp.GraspApproachPolicy`)."""

    target_space: str

    def step(self, q: np.ndarray, target: np.ndarray) -> np.ndarray: ...


class StraightLinePolicy:
    """``P = Q + min(1, s / ||G - Q||) (G - Q)``, ``s = max_step`` (configuration units/tick)."""

    target_space = "configuration"

    def __init__(self, max_step: float) -> None:
        self.max_step = positive(max_step, name="max_step")

    def step(self, q: np.ndarray, target: np.ndarray) -> np.ndarray:
        d = target - q
        n = math.sqrt(d.dot(d))
        if n > self.max_step:
            d *= self.max_step / n
        d += q
        return d

    def __repr__(self) -> str:
        return f"StraightLinePolicy(max_step={self.max_step})"


class WorkspaceLinePolicy:
    """End effector along the straight workspace line to the goal position.

    ``dx = min(1, s / ||g - phi(Q)||) (g - phi(Q))``, ``s = max_step`` (metres per tick), then
    ``P = Q + J^T (J J^T + lambda^2 I)^{-1} dx`` (damped least squares, ``J`` the positional
    rows of the Jacobian at ``Q``).

    Args:
        fk: ``q -> (3,)`` end-effector position.
        jacobian: ``q -> (3, dof)`` or ``(6, dof)`` (linear rows first, as pinocchio's
            LOCAL_WORLD_ALIGNED frame Jacobian).
        max_step: workspace step limit per tick.
        damping: ``lambda >= 0``.
    """

    target_space = "workspace"

    def __init__(
        self,
        *,
        fk: Callable[[np.ndarray], Any],
        jacobian: Callable[[np.ndarray], Any],
        max_step: float,
        damping: float = 1e-3,
    ) -> None:
        if not callable(fk):
            raise InvalidInputError(f"fk: expected a callable q -> (3,), got {fk!r}")
        if not callable(jacobian):
            raise InvalidInputError(
                f"jacobian: expected a callable q -> (3|6, dof), got {jacobian!r}"
            )
        self.fk = fk
        self.jacobian = jacobian
        self.max_step = positive(max_step, name="max_step")
        self.damping = positive(damping, name="damping", allow_zero=True)
        self._lam2 = self.damping**2 * np.eye(3)

    def step(self, q: np.ndarray, target: np.ndarray) -> np.ndarray:
        x = np.asarray(self.fk(q), dtype=np.float64)
        j = np.asarray(self.jacobian(q), dtype=np.float64)
        if x.shape != (3,):
            raise InvalidInputError(f"fk: returned shape {x.shape}, expected (3,)")
        if j.ndim != 2 or j.shape[0] not in (3, 6) or j.shape[1] != q.shape[0]:
            raise InvalidInputError(
                f"jacobian: returned shape {j.shape}, expected (3|6, {q.shape[0]})"
            )
        j = j[:3]
        dx = target - x
        n = math.sqrt(dx.dot(dx))
        if n > self.max_step:
            dx *= self.max_step / n
        try:
            dq = j.T @ np.linalg.solve(j @ j.T + self._lam2, dx)
        except np.linalg.LinAlgError:
            raise InvalidInputError("jacobian: singular at q; use damping > 0") from None
        return q + dq

    def __repr__(self) -> str:
        return f"WorkspaceLinePolicy(max_step={self.max_step}, damping={self.damping})"

"""Oracle prediction: the robot is told the intended goal (the study's "Right" conditions).

``P(G | xi) = 1`` for the given goal, 0 for the others, whatever the input.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InvalidInputError
from .base import GoalPrediction

__all__ = ["OraclePredictor"]


class OraclePredictor:
    """Always predicts ``goal`` (an index into the goal set of ``n_goals`` goals)."""

    space: str | None = None

    def __init__(self, n_goals: int, *, goal: int) -> None:
        if isinstance(n_goals, bool) or not isinstance(n_goals, (int, np.integer)) or n_goals < 1:
            raise InvalidInputError(f"n_goals: must be an integer >= 1, got {n_goals!r}")
        self._n = int(n_goals)
        self.set_goal(goal)

    @property
    def n_goals(self) -> int:
        return self._n

    @property
    def goal(self) -> int:
        return self._goal

    def set_goal(self, goal: int, *, n_goals: int | None = None) -> None:
        """Tell the robot the goal (optionally for a goal set of a new size)."""
        n = self._n if n_goals is None else n_goals
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise InvalidInputError(f"n_goals: must be an integer >= 1, got {n!r}")
        if isinstance(goal, bool) or not isinstance(goal, (int, np.integer)) or not 0 <= goal < n:
            raise InvalidInputError(f"goal: must be an index in [0, {n}), got {goal!r}")
        self._n = int(n)
        self._goal = int(goal)
        p = np.zeros(self._n)
        p[self._goal] = 1.0
        p.setflags(write=False)
        self._prediction = GoalPrediction(p, self._goal)

    def set_points(self, points: Any) -> None:
        """Goals changed: keeps the goal index if it is still valid, else asks for set_goal."""
        n = len(points)
        if not self._goal < n:
            raise InvalidInputError(
                f"points: the oracle goal {self._goal} is not among the {n} new goals; "
                "call set_goal(goal, n_goals=...)"
            )
        self.set_goal(self._goal, n_goals=n)

    def reset(self, start: Any = None) -> None:
        """The oracle keeps no history."""

    def update(self, x: Any = None) -> GoalPrediction:
        return self._prediction

    _update = update

"""Goals that move during a trial, and how a move is logged so a replay moves them too.

When an object is nudged (a missed grasp, a knock), its goal follows it: ``G_k <- G_k'``. The
trial logs one ``goal_moved`` event per moved goal at the tick it takes effect (goal name and
position, metres, world frame; ``app.trial.events``), and an offline replay applies the same
moves at the same ticks (``GoalMoves``), so it predicts over the goals the robot predicted over.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import InvalidInputError
from .goals import GoalSet

__all__ = ["GoalMoves", "moved_goals"]


def moved_goals(
    goals: GoalSet,
    moves: dict[int, tuple[np.ndarray, np.ndarray | None]],
) -> GoalSet:
    """``goals`` with goal ``k`` at ``moves[k] = (position, configuration or None)``."""
    positions = goals.positions.copy()
    configurations = None if goals.configurations is None else goals.configurations.copy()
    for k, (position, configuration) in moves.items():
        positions[k] = position
        if configuration is not None:
            if configurations is None:
                raise InvalidInputError("moves: the goal set has no configurations to move")
            configurations[k] = configuration
    return GoalSet(
        goals.names,
        positions,
        goals.orientations,
        configurations,
        standoffs=goals.standoffs,
        envelopes=goals.envelopes,
    )


@dataclass(frozen=True)
class GoalMoves:
    """The goal moves of one logged trajectory: from row ``rows[i]`` on (before that row's
    prediction), goal ``goals[i]`` is at ``positions[i]``."""

    rows: np.ndarray  # (m,) sample rows (0-based, ascending)
    goals: np.ndarray  # (m,) goal indices
    positions: np.ndarray  # (m, 3)

    @classmethod
    def from_moves(
        cls, moves: Iterable[tuple[int, str, Sequence[float]]], names: Sequence[str]
    ) -> GoalMoves:
        """From ``(row, goal name, position)`` triples (any order) over the goals ``names``."""
        rows, goals, positions = [], [], []
        for row, name, position in moves:
            if name not in names:
                raise InvalidInputError(
                    f"a goal move at row {row}: no goal called {name!r} in {list(names)}"
                )
            rows.append(int(row))
            goals.append(list(names).index(name))
            positions.append(np.asarray(position, dtype=float))
        order = np.argsort(rows, kind="stable")
        return cls(
            np.asarray(rows, dtype=int)[order],
            np.asarray(goals, dtype=int)[order],
            np.asarray(positions, dtype=float).reshape(-1, 3)[order],
        )

    def __len__(self) -> int:
        return len(self.rows)

    def by_row(self) -> dict[int, list[tuple[int, np.ndarray]]]:
        """``{row: [(goal, position), ...]}``, the moves that take effect at each row."""
        out: dict[int, list[tuple[int, np.ndarray]]] = {}
        for row, goal, position in zip(self.rows, self.goals, self.positions, strict=True):
            out.setdefault(int(row), []).append((int(goal), position))
        return out

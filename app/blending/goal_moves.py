"""Goals that move during a trial, and how a move is logged so a replay moves them too.

When an object is nudged (a missed grasp, a knock), its goal follows it: ``G_k <- G_k'``. The
trial logs one event per moved goal at the tick it takes effect,
``goal_moved:<name>@<x>,<y>,<z>`` (metres, world frame, micrometre resolution), and an offline
replay applies the same moves at the same ticks (``GoalMoves``), so it predicts over the goals
the robot predicted over.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InvalidInputError
from .goals import GoalSet

__all__ = ["GOAL_MOVED", "GoalMoves", "goal_moved_event", "moved_goals", "parse_goal_moved"]

GOAL_MOVED = "goal_moved"


def goal_moved_event(name: str, position: Sequence[float]) -> str:
    """``goal_moved:<name>@x,y,z`` for a goal now at ``position`` (3,)."""
    x, y, z = (float(v) for v in position)
    if not math.isfinite(x + y + z):
        raise InvalidInputError(f"position: goal {name!r} moved to a non-finite {position!r}")
    return f"{GOAL_MOVED}:{name}@{x:.6f},{y:.6f},{z:.6f}"


def parse_goal_moved(event: str) -> tuple[str, np.ndarray] | None:
    """``(name, position)`` of a ``goal_moved`` event; ``None`` for any other event."""
    if not event.startswith(GOAL_MOVED + ":"):
        return None
    name, sep, coords = event[len(GOAL_MOVED) + 1 :].rpartition("@")
    values = coords.split(",")
    if not sep or not name or len(values) != 3:
        raise InvalidInputError(f"event {event!r}: expected 'goal_moved:<name>@x,y,z'")
    try:
        position = np.array([float(v) for v in values])
    except ValueError:
        raise InvalidInputError(f"event {event!r}: coordinates are not numbers") from None
    return name, position


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
    return GoalSet(goals.names, positions, goals.orientations, configurations)


@dataclass(frozen=True)
class GoalMoves:
    """The goal moves of one logged trajectory: from row ``rows[i]`` on (before that row's
    prediction), goal ``goals[i]`` is at ``positions[i]``."""

    rows: np.ndarray  # (m,) sample rows (0-based, ascending)
    goals: np.ndarray  # (m,) goal indices
    positions: np.ndarray  # (m, 3)

    @classmethod
    def from_events(cls, events: Iterable[tuple[int, Any]], names: Sequence[str]) -> GoalMoves:
        """From ``(row, events)`` pairs; ``events`` a list of strings or its JSON text."""
        rows, goals, positions = [], [], []
        for row, evs in events:
            if isinstance(evs, str):
                evs = json.loads(evs) if evs.startswith("[") else [evs]
            for event in evs if evs is not None else ():
                parsed = parse_goal_moved(str(event))
                if parsed is None:
                    continue
                name, position = parsed
                if name not in names:
                    raise InvalidInputError(
                        f"event {event!r} at row {row}: no goal called {name!r} in {list(names)}"
                    )
                rows.append(int(row))
                goals.append(list(names).index(name))
                positions.append(position)
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

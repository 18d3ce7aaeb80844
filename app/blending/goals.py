"""The goal set G: named goals with workspace positions, optional orientations and configurations.

Goals are known only at run time and may change in number and place between (or during)
trials: build a new :class:`GoalSet` and hand it to ``PolicyBlender.set_goals``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._checks import as_finite_array, as_points
from .errors import InvalidInputError

__all__ = ["GoalSet"]


@dataclass(frozen=True, eq=False)
class GoalSet:
    """A non-empty set of ``n`` goals.

    Attributes:
        names: ``n`` distinct goal names.
        positions: ``(n, 3)`` workspace positions (metres).
        orientations: ``(n, 4)`` unit quaternions (w, x, y, z), or ``None``.
        configurations: ``(n, dof)`` goal configurations (e.g. grasp configurations by IK),
            or ``None`` when only workspace goals are known.
    """

    names: tuple[str, ...]
    positions: np.ndarray
    orientations: np.ndarray | None = None
    configurations: np.ndarray | None = None

    def __init__(
        self,
        names: Sequence[str],
        positions: Any,
        orientations: Any | None = None,
        configurations: Any | None = None,
    ) -> None:
        names_t = tuple(names)
        if not names_t:
            raise InvalidInputError("names: the goal set is empty; give at least one goal")
        if not all(isinstance(n, str) and n for n in names_t):
            raise InvalidInputError(f"names: every name must be a non-empty string, got {names_t}")
        if len(set(names_t)) != len(names_t):
            raise InvalidInputError(f"names: goal names must be distinct, got {names_t}")
        n = len(names_t)
        pos = as_points(positions, name="positions", dim=3)
        if pos.shape[0] != n:
            raise InvalidInputError(
                f"positions: expected {n} rows (one per name), got shape {pos.shape}"
            )
        ori = None
        if orientations is not None:
            ori = as_finite_array(orientations, name="orientations", ndim=2, dim=4)
            if ori.shape[0] != n:
                raise InvalidInputError(
                    f"orientations: expected {n} rows (one per name), got shape {ori.shape}"
                )
            norms = np.linalg.norm(ori, axis=1)
            if (np.abs(norms - 1.0) > 1e-6).any():
                raise InvalidInputError(
                    f"orientations: quaternions must have unit norm, got norms {norms.tolist()}"
                )
        cfg = None
        if configurations is not None:
            cfg = as_points(configurations, name="configurations")
            if cfg.shape[0] != n:
                raise InvalidInputError(
                    f"configurations: expected {n} rows (one per name), got shape {cfg.shape}"
                )
        for arr in (pos, ori, cfg):
            if arr is not None:
                arr.setflags(write=False)
        object.__setattr__(self, "names", names_t)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "orientations", ori)
        object.__setattr__(self, "configurations", cfg)

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of the goal called ``name``."""
        try:
            return self.names.index(name)
        except ValueError:
            raise InvalidInputError(
                f"name: no goal called {name!r}; goals are {list(self.names)}"
            ) from None

    def points(self, space: str) -> np.ndarray:
        """The goals as points of ``space``: ``"workspace"`` (positions) or ``"configuration"``."""
        if space == "workspace":
            return self.positions
        if space == "configuration":
            if self.configurations is None:
                raise InvalidInputError(
                    "space: 'configuration' needs goal configurations; this GoalSet has none"
                )
            return self.configurations
        raise InvalidInputError(f"space: must be 'workspace' or 'configuration', got {space!r}")

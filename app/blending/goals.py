"""The goal set G: named goals with workspace positions, optional orientations and configurations.

A goal may be a grasp frame: the position and orientation of the tool centre point (TCP) at
the grasp, a pre-grasp ``standoff`` back along the gripper's approach axis ``a`` (the TCP's z
axis: ``pregrasp = position - standoff a``) and the ``envelope`` of the object it grasps, which
a grasping policy must straddle and every other goal's policy must clear.

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

__all__ = ["GoalSet", "quaternion_matrix"]

ENVELOPE_COLUMNS = ("radius", "top", "half_width")
"""The columns of ``GoalSet.envelopes``."""


@dataclass(frozen=True, eq=False)
class GoalSet:
    """A non-empty set of ``n`` goals.

    Attributes:
        names: ``n`` distinct goal names.
        positions: ``(n, 3)`` workspace positions (metres).
        orientations: ``(n, 4)`` unit quaternions (w, x, y, z), or ``None``.
        configurations: ``(n, dof)`` goal configurations (e.g. grasp configurations by IK),
            or ``None`` when only workspace goals are known.
        standoffs: ``(n,)`` pre-grasp distances back along the approach axis (metres, > 0),
            or ``None``; needs ``orientations``.
        envelopes: ``(n, 3)`` the grasped objects as upright cylinders on the grasp point's
            vertical, columns ``ENVELOPE_COLUMNS``: footprint radius, height of the object's
            top above the grasp point, half-width across the fingers' closing direction
            (metres); or ``None``.
    """

    names: tuple[str, ...]
    positions: np.ndarray
    orientations: np.ndarray | None = None
    configurations: np.ndarray | None = None
    standoffs: np.ndarray | None = None
    envelopes: np.ndarray | None = None

    def __init__(
        self,
        names: Sequence[str],
        positions: Any,
        orientations: Any | None = None,
        configurations: Any | None = None,
        *,
        standoffs: Any | None = None,
        envelopes: Any | None = None,
    ) -> None:
        names_t = _names(names)
        n = len(names_t)
        pos = as_points(positions, name="positions", dim=3)
        _rows("positions", pos, n)
        ori = None if orientations is None else _orientations(orientations, n)
        cfg = None
        if configurations is not None:
            cfg = as_points(configurations, name="configurations")
            _rows("configurations", cfg, n)
        off = None if standoffs is None else _standoffs(standoffs, n, oriented=ori is not None)
        env = None if envelopes is None else _envelopes(envelopes, n)
        for arr in (pos, ori, cfg, off, env):
            if arr is not None:
                arr.setflags(write=False)
        object.__setattr__(self, "names", names_t)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "orientations", ori)
        object.__setattr__(self, "configurations", cfg)
        object.__setattr__(self, "standoffs", off)
        object.__setattr__(self, "envelopes", env)

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

    def rotations(self) -> np.ndarray:
        """``(n, 3, 3)`` the goals' orientations as rotation matrices (columns: the TCP's axes
        in the world frame)."""
        if self.orientations is None:
            raise InvalidInputError("orientations: this GoalSet has none; give them to build it")
        return np.array([quaternion_matrix(w) for w in self.orientations])

    def pregrasp_positions(self) -> np.ndarray:
        """``(n, 3)`` pre-grasp points ``position - standoff a``, ``a`` the approach axis (the
        third column of each goal's rotation)."""
        if self.standoffs is None:
            raise InvalidInputError("standoffs: this GoalSet has none; give them to build it")
        axes = self.rotations()[:, :, 2]
        return self.positions - self.standoffs[:, None] * axes

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


def quaternion_matrix(wxyz: Any) -> np.ndarray:
    """The rotation matrix of a unit quaternion ``(w, x, y, z)``."""
    w, x, y, z = (float(v) for v in wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _names(names: Sequence[str]) -> tuple[str, ...]:
    names_t = tuple(names)
    if not names_t:
        raise InvalidInputError("names: the goal set is empty; give at least one goal")
    if not all(isinstance(n, str) and n for n in names_t):
        raise InvalidInputError(f"names: every name must be a non-empty string, got {names_t}")
    if len(set(names_t)) != len(names_t):
        raise InvalidInputError(f"names: goal names must be distinct, got {names_t}")
    return names_t


def _rows(name: str, arr: np.ndarray, n: int) -> None:
    if arr.shape[0] != n:
        raise InvalidInputError(f"{name}: expected {n} rows (one per name), got shape {arr.shape}")


def _orientations(orientations: Any, n: int) -> np.ndarray:
    """``(n, 4)`` unit quaternions."""
    ori = as_finite_array(orientations, name="orientations", ndim=2, dim=4)
    _rows("orientations", ori, n)
    norms = np.linalg.norm(ori, axis=1)
    if (np.abs(norms - 1.0) > 1e-6).any():
        raise InvalidInputError(
            f"orientations: quaternions must have unit norm, got norms {norms.tolist()}"
        )
    return ori


def _standoffs(standoffs: Any, n: int, *, oriented: bool) -> np.ndarray:
    """``(n,)`` distances > 0 along the approach axis (which needs the orientations)."""
    if not oriented:
        raise InvalidInputError(
            "standoffs: a pre-grasp standoff runs along the approach axis; give the"
            " goals' orientations too"
        )
    off = as_finite_array(standoffs, name="standoffs", ndim=1)
    if off.shape[0] != n or not (off > 0.0).all():
        raise InvalidInputError(
            f"standoffs: expected {n} distances > 0 (one per name), got {off.tolist()}"
        )
    return off


def _envelopes(envelopes: Any, n: int) -> np.ndarray:
    """``(n, 3)`` rows of ``ENVELOPE_COLUMNS`` with radius and half-width > 0."""
    env = as_finite_array(envelopes, name="envelopes", ndim=2, dim=3)
    if env.shape[0] != n or not (env[:, 0] > 0.0).all() or not (env[:, 2] > 0.0).all():
        raise InvalidInputError(
            f"envelopes: expected {n} rows of {ENVELOPE_COLUMNS} with radius and"
            f" half_width > 0, got {env.tolist()}"
        )
    return env

"""The browser gizmo as an input source: the UI thread sets an absolute end-effector target."""

from __future__ import annotations

import threading

import numpy as np

from app.teleop.errors import InvalidTargetError
from app.teleop.reach import finite3
from app.teleop.types import TeleopCommand, TrialObservation


class GizmoInput:
    """Thread-safe absolute target: ``set_target`` from UI callbacks, ``command`` from the loop.

    The target starts at the TCP (first observation). ``request_grasp()`` (a button) makes the
    next command ask for a grasp once.
    """

    def __init__(self, target: np.ndarray | None = None) -> None:
        self._lock = threading.Lock()
        self._target = None if target is None else checked_position(target)
        self._grasp = False

    def set_target(self, target: np.ndarray) -> None:
        """Set the raw target (3,); a NaN, infinite or misshapen target raises, state unchanged."""
        checked = checked_position(target)
        with self._lock:
            self._target = checked

    def request_grasp(self) -> None:
        with self._lock:
            self._grasp = True

    @property
    def target(self) -> np.ndarray | None:
        with self._lock:
            return None if self._target is None else self._target.copy()

    def command(self, obs: TrialObservation) -> TeleopCommand:
        with self._lock:
            if self._target is None:
                self._target = obs.ee.copy()
            grasp, self._grasp = self._grasp, False
            return TeleopCommand(self._target.copy(), grasp)


def checked_position(target: np.ndarray) -> np.ndarray:
    """``target`` as a fresh (3,) float array; ``InvalidTargetError`` if it is not 3 finite
    numbers."""
    arr = np.asarray(target, dtype=float).reshape(-1)
    if not finite3(arr):
        raise InvalidTargetError(f"gizmo target must be 3 finite numbers, got {target!r}")
    return arr.copy()

"""Keyboard-style nudges as an input source: fixed steps along x, y, z and a grasp key."""

from __future__ import annotations

import threading

import numpy as np

from app.teleop.errors import TeleopError
from app.teleop.types import TeleopCommand, TrialObservation

# key -> (axis, sign); "g" or space asks for a grasp.
KEYMAP: dict[str, tuple[int, float]] = {
    "w": (0, 1.0),
    "s": (0, -1.0),
    "a": (1, 1.0),
    "d": (1, -1.0),
    "e": (2, 1.0),
    "q": (2, -1.0),
}
GRASP_KEYS = ("g", " ")


class KeyboardInput:
    """Each key press moves the target by ``step`` metres; the target stays inside the reach.

    Nudges are applied to the last clamped target, so pressing against a wall does not build up
    an invisible offset. Thread-safe: ``press`` runs on the UI thread.
    """

    def __init__(self, *, step: float = 0.01) -> None:
        if not 0.0 < step <= 0.1:
            raise TeleopError(f"step: must be in (0, 0.1] m, got {step}")
        self.step = step
        self._lock = threading.Lock()
        self._pending = np.zeros(3)
        self._grasp = False

    def nudge(self, axis: int, sign: float) -> None:
        if axis not in (0, 1, 2) or sign not in (-1.0, 1.0, -1, 1):
            raise TeleopError(f"nudge: axis must be 0, 1 or 2 and sign +-1, got {axis}, {sign}")
        with self._lock:
            self._pending[axis] += sign * self.step

    def press(self, key: str) -> None:
        """Handle one key press (see ``KEYMAP`` and ``GRASP_KEYS``); unknown keys raise."""
        key = key.lower() if key != " " else key
        if key in GRASP_KEYS:
            with self._lock:
                self._grasp = True
        elif key in KEYMAP:
            self.nudge(*KEYMAP[key])
        else:
            raise TeleopError(f"key {key!r} does nothing; use {sorted(KEYMAP)} or 'g'")

    def command(self, obs: TrialObservation) -> TeleopCommand:
        with self._lock:
            pending, self._pending = self._pending, np.zeros(3)
            grasp, self._grasp = self._grasp, False
        target = obs.reach.clamp(obs.user_target + pending)
        return TeleopCommand(target, grasp)

"""Held keys as an input source: while a key is held the target moves at a fixed speed.

A key moves the target along one world axis: W/S away from / back toward the robot base (x),
A/D to the left / right (y), R/F up / down (z); G (or space) asks for a grasp. Each control
tick the target moves ``speed * dt`` along every held direction (two keys: a diagonal), so the
distance travelled is ``speed`` times how long the keys were held, whatever the keyboard's
auto-repeat does. A tap shorter than ``tap_s`` still moves ``speed * tap_s``: a press always
does something visible, however quickly it was released between two ticks.

Moves start from the last clamped target, so holding a key against the reach's wall does not
build up an invisible offset. Thread-safe: ``hold``/``release`` run on UI threads,
``command`` on the control thread.
"""

from __future__ import annotations

import threading

import numpy as np

from app.teleop.errors import TeleopError
from app.teleop.types import TeleopCommand, TrialObservation

KEY_SPEED_M_S = 0.10
"""Target speed while a key is held, m/s (a 40 cm reach takes 4 s)."""

TAP_S = 0.08
"""A press is worth at least this many seconds of motion (a tap moves 8 mm at 0.1 m/s)."""

# key -> (axis, sign)
KEYMAP: dict[str, tuple[int, float]] = {
    "w": (0, 1.0),
    "s": (0, -1.0),
    "a": (1, 1.0),
    "d": (1, -1.0),
    "r": (2, 1.0),
    "f": (2, -1.0),
}
GRASP_KEYS = ("g", " ")


def _key(key: str) -> str:
    return key if key == " " else key.lower()


class KeyboardInput:
    """Velocity input from held keys (see the module docstring for the key map)."""

    def __init__(self, *, speed: float = KEY_SPEED_M_S, tap_s: float = TAP_S) -> None:
        if not 0.0 < speed <= 1.0:
            raise TeleopError(f"speed: must be in (0, 1] m/s, got {speed}")
        if not 0.0 <= tap_s <= 1.0:
            raise TeleopError(f"tap_s: must be in [0, 1] s, got {tap_s}")
        self.speed = float(speed)
        self.tap_s = float(tap_s)
        self._lock = threading.Lock()
        self._held: dict[str, float] = {}  # key -> seconds of motion applied while held
        self._owed = np.zeros(3)  # displacement owed by taps released before they moved enough
        self._grasp = False

    # -- UI side ---------------------------------------------------------------------------
    def hold(self, key: str) -> None:
        """Key ``key`` went down (an auto-repeat of a held key changes nothing)."""
        key = _key(key)
        if key in GRASP_KEYS:
            with self._lock:
                self._grasp = True
            return
        if key not in KEYMAP:
            raise TeleopError(f"key {key!r} does nothing; use {sorted(KEYMAP)} or 'g'")
        with self._lock:
            self._held.setdefault(key, 0.0)

    def release(self, key: str) -> None:
        """Key ``key`` went up; a press shorter than ``tap_s`` is topped up to a tap."""
        key = _key(key)
        with self._lock:
            moved = self._held.pop(key, None)
            if moved is not None and moved < self.tap_s:
                axis, sign = KEYMAP[key]
                self._owed[axis] += sign * self.speed * (self.tap_s - moved)

    def release_all(self, *, discard: bool = False) -> None:
        """Every key up (a lost tab, a pause). ``discard`` also drops owed taps and grasps, so
        nothing pressed before a pause is applied after it."""
        with self._lock:
            keys = list(self._held)
        for key in keys:
            self.release(key)
        if discard:
            with self._lock:
                self._owed[:] = 0.0
                self._grasp = False

    def press(self, key: str) -> None:
        """A tap: ``hold`` then ``release`` (moves ``speed * tap_s``)."""
        self.hold(key)
        if _key(key) not in GRASP_KEYS:
            self.release(key)

    @property
    def held(self) -> frozenset[str]:
        with self._lock:
            return frozenset(self._held)

    # -- control loop side -------------------------------------------------------------------
    def command(self, obs: TrialObservation) -> TeleopCommand:
        """``target = clamp(user_target + speed * dt * sum(held directions) + owed taps)``."""
        step, grasp = self.step(1.0 / obs.rate_hz)
        target = obs.reach.clamp(obs.user_target + step)
        return TeleopCommand(target, grasp)

    def step(self, dt: float) -> tuple[np.ndarray, bool]:
        """One tick of ``dt`` seconds: the keys' displacement ``speed * dt * sum(held
        directions) + owed taps`` (3,) and whether a grasp was asked for (each once)."""
        with self._lock:
            step = self._owed.copy()
            self._owed[:] = 0.0
            for key in self._held:
                axis, sign = KEYMAP[key]
                step[axis] += sign * self.speed * dt
                self._held[key] += dt
            grasp, self._grasp = self._grasp, False
        return step, grasp

    @property
    def moving(self) -> bool:
        """True while a key is held or a tap's motion is still owed."""
        with self._lock:
            return bool(self._held) or any(self._owed.tolist())

"""The participant's two inputs as one ``InputSource``: the gizmo (absolute) and held keys.

Each control tick asks ``command(obs)``: a gizmo pose that arrived since the last tick wins;
otherwise held keys move the last clamped target (``KeyboardInput``, a fixed speed while held)
and the gizmo's target follows, so the two never fight. Grasp requests from the button, the G
key, or either source are merged. The time from a gizmo pose arriving (``set_target``) to the
tick whose command uses it is recorded in ``latencies_s`` (the server benchmark reports it).

While ``frozen`` (a pause: by the experimenter, a lost tab, a fault) every input is refused
with :class:`InputFrozen` and nothing is queued, so nothing done during a pause is applied
after it; ``freeze()`` also lets go of held keys and drops pending grasps and poses.
"""

from __future__ import annotations

import threading
import time
from collections import deque

import numpy as np

from app.teleop.gizmo import GizmoInput
from app.teleop.keyboard import KEY_SPEED_M_S, KeyboardInput
from app.teleop.types import TeleopCommand, TrialObservation


class InputFrozen(RuntimeError):
    """An input arrived while the trial is paused; it was not applied."""


class ParticipantInput:
    """Gizmo + keyboard, thread-safe: UI callbacks write, the control loop reads."""

    def __init__(
        self, *, start_target: np.ndarray | None = None, key_speed_m_s: float = KEY_SPEED_M_S
    ) -> None:
        self.gizmo = GizmoInput(start_target)
        self.keyboard = KeyboardInput(speed=key_speed_m_s)
        self._lock = threading.Lock()
        self._seq = 0
        self._used = 0
        self._arrival: float | None = None
        self._grasp = False
        self._frozen = False
        self.latencies_s: deque[float] = deque(maxlen=20000)
        self.last_target: np.ndarray | None = None
        self.key_moved = threading.Event()
        """Set when held keys moved the target (the UI moves the gizmo to ``last_target``)."""

    # -- pause -----------------------------------------------------------------------------------
    @property
    def frozen(self) -> bool:
        return self._frozen

    def freeze(self) -> None:
        """Refuse input until ``thaw``; drop what is pending (held keys, grasps, poses)."""
        with self._lock:
            self._frozen = True
            self._grasp = False
            self._used = self._seq
        self.keyboard.release_all(discard=True)

    def thaw(self) -> None:
        with self._lock:
            self._frozen = False

    def _check(self, what: str) -> None:
        if self._frozen:
            raise InputFrozen(f"{what} while paused: not applied")

    # -- UI side -------------------------------------------------------------------------------
    def set_target(self, target: np.ndarray) -> None:
        """A gizmo pose (3,); a non-finite one raises ``InvalidTargetError``, state unchanged."""
        self._check("handle moved")
        self.gizmo.set_target(target)
        with self._lock:
            self._seq += 1
            self._arrival = time.perf_counter()

    def key_down(self, key: str) -> None:
        """A steering or grasp key went down (see ``app.teleop.keyboard.KEYMAP``)."""
        self._check(f"key {key!r} pressed")
        self.keyboard.hold(key)

    def key_up(self, key: str) -> None:
        """A key went up; always accepted (a key released during a pause is simply up)."""
        self.keyboard.release(key)
        if self._frozen:
            self.keyboard.release_all(discard=True)

    def request_grasp(self) -> None:
        self._check("grasp")
        with self._lock:
            self._grasp = True

    # -- control loop side -----------------------------------------------------------------------
    def command(self, obs: TrialObservation) -> TeleopCommand:
        with self._lock:
            fresh = self._seq != self._used
            self._used = self._seq
            arrival = self._arrival
            grasp, self._grasp = self._grasp, False
        from_gizmo = self.gizmo.command(obs)
        keys_moving = self.keyboard.moving
        from_keys = self.keyboard.command(obs)
        if fresh:
            target = from_gizmo.target
            if arrival is not None:
                self.latencies_s.append(time.perf_counter() - arrival)
        elif keys_moving:
            target = from_keys.target
            self.gizmo.set_target(target)
            self.key_moved.set()
        else:
            target = from_gizmo.target
        self.last_target = np.array(target, dtype=float)
        return TeleopCommand(target, bool(grasp or from_gizmo.grasp or from_keys.grasp))

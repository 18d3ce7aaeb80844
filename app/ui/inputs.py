"""The participant's two inputs as one ``InputSource``: the gizmo (absolute) and the keys (nudges).

Each control tick asks ``command(obs)``: a gizmo pose that arrived since the last tick wins;
otherwise pending key nudges move the last clamped target (``KeyboardInput``) and the gizmo's
target follows, so the two never fight. Grasp requests from the button, the G key, or either
source are merged. The time from a gizmo pose arriving (``set_target``) to the tick whose
command uses it is recorded in ``latencies_s`` (the server benchmark reports it).
"""

from __future__ import annotations

import threading
import time
from collections import deque

import numpy as np

from app.teleop.gizmo import GizmoInput
from app.teleop.keyboard import KeyboardInput
from app.teleop.types import TeleopCommand, TrialObservation


class ParticipantInput:
    """Gizmo + keyboard, thread-safe: UI callbacks write, the control loop reads."""

    def __init__(self, *, start_target: np.ndarray | None = None, key_step_m: float = 0.02):
        self.gizmo = GizmoInput(start_target)
        self.keyboard = KeyboardInput(step=key_step_m)
        self._lock = threading.Lock()
        self._seq = 0
        self._used = 0
        self._arrival: float | None = None
        self._grasp = False
        self.latencies_s: deque[float] = deque(maxlen=20000)
        self.last_target: np.ndarray | None = None
        self.key_moved = threading.Event()
        """Set when a key nudge moved the target (the UI moves the gizmo to ``last_target``)."""

    # -- UI side -------------------------------------------------------------------------------
    def set_target(self, target: np.ndarray) -> None:
        """A gizmo pose (3,); a non-finite one raises ``InvalidTargetError``, state unchanged."""
        self.gizmo.set_target(target)
        with self._lock:
            self._seq += 1
            self._arrival = time.perf_counter()

    def nudge(self, delta: np.ndarray) -> None:
        """A key press: move the target by ``delta`` (one axis, +-step)."""
        delta = np.asarray(delta, dtype=float)
        axis = int(np.argmax(np.abs(delta)))
        self.keyboard.nudge(axis, 1.0 if delta[axis] > 0 else -1.0)

    def request_grasp(self) -> None:
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
        from_keys = self.keyboard.command(obs)
        keys_moved = not np.allclose(from_keys.target, obs.reach.clamp(obs.user_target))
        if fresh:
            target = from_gizmo.target
            if arrival is not None:
                self.latencies_s.append(time.perf_counter() - arrival)
        elif keys_moved:
            target = from_keys.target
            self.gizmo.set_target(target)
            self.key_moved.set()
        else:
            target = from_gizmo.target
        self.last_target = np.array(target, dtype=float)
        return TeleopCommand(target, bool(grasp or from_gizmo.grasp or from_keys.grasp))

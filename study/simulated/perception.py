"""What a simulated user sees: the robot as it was ``tau`` seconds ago.

Observations arrive once per control tick. :class:`DelayedView` keeps the last
``lag + window + 1`` of them, ``lag = round(tau * rate)``, and reports the seen end-effector
position ``ee(t - tau)``, the gizmo (the user's own clamped target) as shown then and its
velocity, its velocity ``(ee(t - tau) - ee(t - tau - window)) / window`` and
which object the gripper held. Only quantities a participant can see are kept: never the
arbitration value, the prediction or any condition label.
"""

from __future__ import annotations

from collections import deque
from typing import NamedTuple

import numpy as np


class Seen(NamedTuple):
    """One delayed percept (a named tuple: made every tick, at a third of a frozen dataclass's
    cost)."""

    t: float  # when it happened (trial time, s)
    ee: np.ndarray  # gripper position (3,)
    velocity: np.ndarray  # gripper velocity (3,), m/s
    grasped: str | None  # name of the object in the gripper, if any
    plan: np.ndarray  # where the user meant the gripper to be at that time (3,)
    follow: np.ndarray  # where the gripper would be had it followed the user's input (3,)
    own: np.ndarray  # the user's own (clamped) target as shown by the gizmo then (3,)
    own_velocity: np.ndarray  # its velocity (3,), m/s: the user's input motion


class DelayedView:
    """A fixed-lag buffer of observations (``tau`` seconds behind, velocity over ``window``)."""

    def __init__(self, *, tau: float, rate_hz: float, window_s: float = 0.1) -> None:
        self.lag = max(0, round(tau * rate_hz))
        self.window = max(1, round(window_s * rate_hz))
        self.dt = 1.0 / rate_hz
        self._buf: deque[
            tuple[float, np.ndarray, str | None, np.ndarray, np.ndarray, np.ndarray]
        ] = deque(maxlen=self.lag + self.window + 1)

    def push(
        self,
        t: float,
        ee: np.ndarray,
        grasped: str | None,
        plan: np.ndarray,
        follow: np.ndarray,
        own: np.ndarray,
    ) -> None:
        """Add this tick's observation (arrays are kept by reference: pass fresh ones)."""
        self._buf.append((t, ee, grasped, plan, follow, own))

    def seen(self) -> Seen:
        """The percept ``tau`` seconds ago (the oldest one while fewer have arrived)."""
        buf = self._buf
        n = len(buf)
        i = max(0, n - 1 - self.lag)
        j = max(0, i - self.window)
        t, ee, grasped, plan, follow, own = buf[i]
        if i > j:
            span = (i - j) * self.dt
            velocity = (ee - buf[j][1]) / span
            own_velocity = (own - buf[j][5]) / span
        else:
            velocity = own_velocity = np.zeros(3)
        return Seen(
            t=t,
            ee=ee,
            velocity=velocity,
            grasped=grasped,
            plan=plan,
            follow=follow,
            own=own,
            own_velocity=own_velocity,
        )

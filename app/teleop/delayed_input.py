"""Added latency: an input source whose commands reach the robot a fixed number of ticks late.

``DelayedInput(source, ticks=d)`` answers tick ``k`` with what ``source`` answered at tick
``k - d``: the participant's command takes ``d / rate_hz`` seconds longer to act, as over a slow
link (the latency factors of teleoperation studies). Until the first command has come through,
the robot is told to hold: the last target and the gripper as it is. The source is still asked
every tick with the observation of that tick, so what it sees (the gripper, the robot's motion)
is current and only its effect is late.
"""

from __future__ import annotations

from collections import deque

from app.teleop.errors import TeleopError
from app.teleop.types import InputSource, TeleopCommand, TrialObservation

MAX_DELAY_TICKS = 1000
"""The longest delay accepted (10 s at 100 Hz)."""


class DelayedInput:
    """``source``'s commands, ``ticks`` control ticks late (module docstring)."""

    def __init__(self, source: InputSource, *, ticks: int) -> None:
        if (
            isinstance(ticks, bool)
            or not isinstance(ticks, int)
            or not 0 <= ticks <= MAX_DELAY_TICKS
        ):
            raise TeleopError(f"ticks: a whole number in 0..{MAX_DELAY_TICKS}, got {ticks!r}")
        self.source = source
        self.ticks = ticks
        self._queue: deque[TeleopCommand] = deque()

    def command(self, obs: TrialObservation) -> TeleopCommand:
        self._queue.append(self.source.command(obs))
        if len(self._queue) > self.ticks:
            return self._queue.popleft()
        return TeleopCommand(obs.user_target.copy(), obs.gripper_closed)


def delayed(source: InputSource, *, latency_s: float, rate_hz: float) -> InputSource:
    """``source`` delayed by ``latency_s`` rounded to whole ticks (itself when that is 0)."""
    ticks = round(latency_s * rate_hz)
    return source if ticks == 0 else DelayedInput(source, ticks=ticks)

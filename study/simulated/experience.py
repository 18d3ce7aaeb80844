"""What a participant experienced in one run, from what they saw: the questionnaire's input.

Per tick, with ``w`` the velocity of the user's own input (the gizmo target, as seen) and ``v``
the seen gripper velocity, the disagreement is ``delta = (1 - cos(w, v)) / 2`` in ``[0, 1]``
(0: the robot moves the way the input moves; 1: straight the other way), counted only while
both visibly move (``|v|, |w| > v_min``). ``mean_disagreement`` averages ``delta`` over the
counted ticks (0 if none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from study.simulated._vec import norm


@dataclass(frozen=True)
class RunExperience:
    """One run as its participant lived it: how long, how much the robot went its own way, and
    whether they picked the object up. No condition labels."""

    duration_s: float
    mean_disagreement: float
    success: bool


class ExperienceLog:
    """Accumulates the per-tick disagreement of one run."""

    def __init__(self, *, min_speed: float = 0.03) -> None:
        self.min_speed = min_speed
        self.total = 0.0
        self.count = 0
        self.last_t = 0.0

    def add(self, *, t: float, input_velocity: np.ndarray, robot_velocity: np.ndarray) -> None:
        self.last_t = t
        speed = norm(robot_velocity)
        ask = norm(input_velocity)
        if speed <= self.min_speed or ask <= self.min_speed:
            return
        cos = float(input_velocity @ robot_velocity) / (speed * ask)
        self.total += 0.5 * (1.0 - max(-1.0, min(1.0, cos)))
        self.count += 1

    @property
    def mean_disagreement(self) -> float:
        return self.total / self.count if self.count else 0.0

    def finish(self, *, duration_s: float | None = None, success: bool) -> RunExperience:
        """The run's experience; ``duration_s`` defaults to the last observed time."""
        duration = self.last_t if duration_s is None else duration_s
        if not math.isfinite(duration) or duration < 0:
            duration = self.last_t
        return RunExperience(
            duration_s=float(duration),
            mean_disagreement=self.mean_disagreement,
            success=bool(success),
        )

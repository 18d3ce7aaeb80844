"""Surprise: a robot motion the user did not expect makes them stop and re-plan.

The user's forward model predicts the seen gripper's velocity from their own input: the
gripper follows the handle ``h`` they see like the unassisted arm did in training, plus the
robot's own motion ``b`` they have come to expect (none at first)::

    v_hat = clip((h - x) / lag, v_max) + b

The prediction error is accumulated over a horizon ``H`` -- ``de/dt = (v - v_hat) - e / H``,
so ``e`` is about how far the gripper went astray within the last ``H`` seconds -- and once
``|e| > theta`` the user stops their input for a re-planning time ``T`` (drawn per surprise,
``T = replan_s exp(replan_sigma z)``). No new surprise is registered meanwhile (the
psychological refractory period); afterwards they expect what they saw, ``b <- v - clip(...)``,
``e <- 0``. Between surprises ``b`` habituates to the seen mismatch,
``db/dt = (v - clip(...) - b) / adapt``. Parameters and sources: ``protocols/population.toml``
``[surprise]``.

Only percepts go in: the gripper and the handle as seen ``tau`` ago, and the gripper's seen
velocity.
"""

from __future__ import annotations

import math

import numpy as np

from study.simulated._vec import norm
from study.simulated.population import SurpriseParams


class Surprise:
    """One run's forward-model error and re-planning stops (see the module docstring)."""

    def __init__(self, params: SurpriseParams, *, lag_s: float, rng: np.random.Generator) -> None:
        self.params = params
        self.lag_s = lag_s
        self.rng = rng
        self.error = np.zeros(3)
        self.expected_robot = np.zeros(3)
        self.until = -math.inf
        self.count = 0
        self.stopped_s = 0.0
        self._replanning = False

    def stopped(self, t: float) -> bool:
        """The user is re-planning at ``t`` (their input holds still)."""
        return t < self.until

    def update(
        self, t: float, dt: float, *, ee: np.ndarray, velocity: np.ndarray, handle: np.ndarray
    ) -> bool:
        """Advance by ``dt`` with the seen gripper ``ee``, its ``velocity`` and the seen
        ``handle``; ``True`` while the user is stopped to re-plan (a surprise at ``t`` starts
        one)."""
        p = self.params
        own = (handle - ee) / self.lag_s
        speed = norm(own)
        if speed > p.expected_speed_m_s:
            own = own * (p.expected_speed_m_s / speed)
        mismatch = velocity - own
        if t < self.until:
            self.stopped_s += dt
            return True
        if self._replanning:  # re-planned: what was seen is now expected
            self._replanning = False
            self.expected_robot = mismatch.copy()
            self.error[:] = 0.0
        self.expected_robot += (mismatch - self.expected_robot) * (1.0 - math.exp(-dt / p.adapt_s))
        self.error += dt * ((mismatch - self.expected_robot) - self.error / p.horizon_s)
        if norm(self.error) <= p.threshold_m:
            return False
        self.count += 1
        self.until = t + p.replan_s * math.exp(p.replan_sigma * float(self.rng.standard_normal()))
        self._replanning = True
        self.error[:] = 0.0
        return True

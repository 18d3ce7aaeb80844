"""The user's reaction to the robot: steering against it when it is wrong, relaxing when it helps.

Inputs are percepts only (the robot's seen motion ``v``, the direction ``d`` from the seen
gripper to what the user is aiming at, how far the robot is ahead of the user's own target):

- Opposition (Figs. 14-15): for a direction ``d`` let ``cos = v.d / |v|``, ``c0 =
  cos(opposition_angle)`` and ``o(d) = clip((c0 - cos) / (1 + c0), 0, 1)`` when ``|v| > v_min``
  (0 otherwise). The robot's motion opposes when it heads neither toward the goal nor where the
  user's input sent it: ``o_v = min(o(d_goal), o(d_input))``. A robot that stays away from
  where the user's input should have put it (deviation ``e``, not counting help or a robot
  still on its way) opposes too: ``o_e = clip((|e| - dz) / e_full, 0, 1)``;
  ``o = max(o_v, o_e)``.
- Fight level (harder the longer it lasts): ``df/dt = rate g o - (1 - o) f / decay``,
  ``0 <= f <= f_max``, ``g = 1 + g_T (1 - T)`` faster the less the user trusts the robot
  (:mod:`study.simulated.trust`). The hand is pushed ``push f w`` with ``w = (d - v/|v|) / |d - v/|v||``
  (toward the goal and against the robot's motion), and the corrective gain grows ``(1 + f)``.
- Help (Fig. 12): ``h = clip((lead - 0.01) / lead_full, 0, 1) (1 - o)`` where
  ``lead = |a - target| - |a - ee|`` is how much nearer the goal ``a`` the robot is than the
  user's own target. Relaxation: ``d rho/dt = (relaxer depth h T - rho) / relax_time``: a
  user lets the robot lead as far as they trust it (``T``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from study.simulated._vec import norm
from study.simulated.population import ReactionParams

_NEAR_M = 0.03  # closer than this to the aim point, the direction to it is not meaningful
_DEADZONE_M = 0.02  # deviations smaller than this are not noticed as opposition


def opposition(
    velocity: np.ndarray, direction: np.ndarray, *, angle_deg: float, min_speed: float
) -> float:
    """How much the seen robot motion works against the goal direction ``direction`` (unit)."""
    speed = norm(velocity)
    if speed <= min_speed:
        return 0.0
    cos = float(velocity @ direction) / speed
    c0 = math.cos(math.radians(angle_deg))
    return min(max((c0 - cos) / (1.0 + c0), 0.0), 1.0)


def push_direction(velocity: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Unit vector toward the goal and away from the robot's motion, ``(d - v^) / |d - v^|``."""
    speed = norm(velocity)
    if speed < 1e-9:
        return direction
    w = direction - velocity / speed
    length = norm(w)
    return direction if length < 1e-9 else w / length


def help_level(*, lead_m: float, full_lead_m: float, opposed: float) -> float:
    """How clearly the robot is doing the user's work, in ``[0, 1]``."""
    return min(max((lead_m - 0.01) / full_lead_m, 0.0), 1.0) * (1.0 - opposed)


@dataclass
class Reaction:
    """The user's running reaction state: fight level ``f`` and relaxation ``rho``."""

    params: ReactionParams
    fight: float = 0.0
    relax: float = 0.0
    opposed: float = 0.0
    push: np.ndarray | None = None

    def update(
        self,
        *,
        dt: float,
        velocity: np.ndarray,
        ee: np.ndarray,
        aim: np.ndarray,
        own_target: np.ndarray,
        commanded: np.ndarray | None = None,
        deviation: float = 0.0,
        trust: float = 1.0,
        fight_gain: float = 1.0,
    ) -> None:
        """Advance ``f`` and ``rho`` by ``dt`` given the seen robot, the user's own target and
        ``commanded``, where their input should have put the gripper (forward model); their
        ``trust`` in the robot scales how far they relax, ``fight_gain`` how fast they fight
        (:mod:`study.simulated.trust`)."""
        p = self.params
        to_aim = aim - ee
        dist = norm(to_aim)
        if dist > _NEAR_M:
            direction = to_aim / dist
            o = opposition(
                velocity,
                direction,
                angle_deg=p.opposition_angle_deg,
                min_speed=p.opposition_speed_m_s,
            )
            if o > 0.0 and commanded is not None:
                to_cmd = commanded - ee
                gap = norm(to_cmd)
                if gap > _NEAR_M:
                    o = min(
                        o,
                        opposition(
                            velocity,
                            to_cmd / gap,
                            angle_deg=p.opposition_angle_deg,
                            min_speed=p.opposition_speed_m_s,
                        ),
                    )
            self.push = push_direction(velocity, direction) if o > 0.0 else direction
        else:
            o = 0.0
            self.push = None
        o = max(o, min(max((deviation - _DEADZONE_M) / p.opposition_deviation_m, 0.0), 1.0))
        self.opposed = o
        rate = p.fight_rate_per_s * fight_gain
        self.fight += dt * (rate * o - (1.0 - o) * self.fight / p.fight_decay_s)
        self.fight = min(max(self.fight, 0.0), p.fight_max)
        lead = norm(aim - own_target) - dist
        h = help_level(lead_m=lead, full_lead_m=p.relax_lead_m, opposed=o)
        self.relax += dt * (p.relaxer * p.relax_depth * h * trust - self.relax) / p.relax_time_s
        self.relax = min(max(self.relax, 0.0), 1.0)

    def calm(self) -> None:
        """No fight left: the user learnt that the robot was not working against them."""
        self.fight = 0.0
        self.push = None

    def push_offset(self) -> np.ndarray:
        """Displacement of the hand against the robot, ``push f w`` (zero when calm)."""
        if self.push is None or self.fight <= 0.0:
            return np.zeros(3)
        return self.params.fight_push_m * self.fight * self.push

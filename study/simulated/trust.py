"""Trust in the robot: it falls after the robot's errors and recovers from run to run.

A participant's trust ``T`` in ``[0, 1]`` persists across their runs (one :class:`Trust` per
simulated participant). Within a run, from what the user sees::

    dT/dt = -lambda o(t) T            the robot opposes them (o in [0, 1], study.simulated.reaction)
    T <- T (1 - delta_w)              it takes the gripper to the other object
    T <- T (1 - delta_k)              an object is knocked over or falls off the table

and between runs it recovers toward the participant's initial trust ``T0``::

    T_{n+1} = T_n + rho (T0 - T_n)

(first order, in the manner of Lee & Moray's 1992 time-series model of trust). Trust sets how
far the user lets the robot lead and how fast they fight it (``study.simulated.reaction``): a
relaxer relaxes toward ``relaxer x depth x help x T``, and the fight builds
``1 + g (1 - T)`` times as fast. Parameters and sources: ``protocols/population.toml``
``[trust]``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from study.simulated._vec import norm
from study.simulated.population import TrustParams


class Trust:
    """One participant's trust in the robot across their runs (see the module docstring)."""

    def __init__(self, params: TrustParams) -> None:
        self.params = params
        self.level = min(max(params.initial, 0.0), 1.0)
        self.runs = 0
        self.errors = 0
        self._knocks = 0
        self._near: set[int] = set()

    def new_run(self) -> None:
        """A run starts: after the first, trust has recovered part of its shortfall."""
        if self.runs:
            self.level += self.params.recovery_per_run * (self.params.initial - self.level)
        self.runs += 1
        self._knocks = 0
        self._near = set()

    @property
    def fight_gain(self) -> float:
        """``1 + g (1 - T)``: how much faster the fight builds than at full trust."""
        return 1.0 + self.params.distrust_fight_gain * (1.0 - self.level)

    def observe(
        self,
        dt: float,
        *,
        opposed: float,
        ee: np.ndarray,
        handle: np.ndarray,
        others: Sequence[np.ndarray],
        knocks: int,
    ) -> None:
        """One tick of what the user saw: how much the robot opposed them, the gripper ``ee``
        and their handle, the grasp points of the objects they do not want (``others``,
        each (3,)), and how many objects have been knocked over or off the table so far."""
        p = self.params
        if opposed > 0.0:
            self.level *= math.exp(-p.opposition_loss_per_s * opposed * dt)
        for k in range(len(others)):
            gap = norm(others[k] - ee)
            if gap < p.wrong_approach_m and norm(others[k] - handle) > gap + 0.03:
                if k not in self._near:  # the robot took the gripper there
                    self._near.add(k)
                    self._error(p.wrong_approach_loss)
            elif gap > 2.0 * p.wrong_approach_m:
                self._near.discard(k)
        while self._knocks < knocks:
            self._knocks += 1
            self._error(p.knock_loss)

    def _error(self, loss: float) -> None:
        self.errors += 1
        self.level *= 1.0 - loss

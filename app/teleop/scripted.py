"""A scripted user for tests and simulated participants: straight toward the target, noisy.

The user moves their target at ``speed`` (m/s) toward a hover point ``approach_height`` above
the goal's grasp point (where its object is now, ``obs.grasp_points``), then down to it, with Ornstein-Uhlenbeck noise of standard deviation
``noise`` (m). The raw target is not clamped: at the interface's limit the user keeps pushing.
They ask for a grasp when the TCP is within ``grasp_tolerance`` of the grasp point, or (with
``grasp_when_stalled``) when the TCP has stalled for ``stall_s`` seconds within
``stalled_grasp_radius`` of it (close enough to try anyway). While their object lies knocked
over (``obs.lying``) they wait for it to be stood up again, the hand raised to the hover height
above where they are, clear of its place; then they approach it afresh.
"""

from __future__ import annotations

import math

import numpy as np

from app.teleop.types import TeleopCommand, TrialObservation

NOISE_BATCH = 3 * 256
"""Normal numbers drawn at a time for the noise (a multiple of 3; a generator's draws of ``n``
numbers are its draws of ``n / 3`` threes, one after the other)."""


class ScriptedInput:
    """Seeded scripted user; ``goal`` (index) defaults to the trial's target object."""

    def __init__(
        self,
        *,
        seed: int = 0,
        speed: float = 0.15,
        noise: float = 0.002,
        noise_time_s: float = 0.5,
        approach_height: float = 0.08,
        grasp_tolerance: float = 0.01,
        stall_s: float = 1.5,
        retry_s: float = 1.5,
        goal: int | None = None,
        grasp_when_stalled: bool = True,
        stalled_grasp_radius: float = 0.04,
    ) -> None:
        self.rng = np.random.default_rng(seed)
        self.speed = speed
        self.noise = noise
        self.noise_time_s = noise_time_s
        self.approach_height = approach_height
        self.grasp_tolerance = grasp_tolerance
        self.stall_s = stall_s
        self.retry_s = retry_s
        self.goal = goal
        self.grasp_when_stalled = grasp_when_stalled
        self.stalled_grasp_radius = stalled_grasp_radius
        self._target: tuple[float, float, float] | None = None  # noise-free target
        self._offset = (0.0, 0.0, 0.0)  # Ornstein-Uhlenbeck noise on top of it
        self._phase = "hover"
        self._last_grasp_t = -math.inf
        self._stall_ref: tuple[float, list[float]] | None = None
        self._noise_cache: tuple[float, float, float] | None = None
        self._drawn: list[float] = []  # normal numbers drawn ahead (``_normals``)
        self._next_drawn = 0

    @property
    def phase(self) -> str:
        return self._phase

    def command(self, obs: TrialObservation) -> TeleopCommand:
        # three-vectors in scalars (lists): cheaper per tick than small array operations
        dt = 1.0 / obs.rate_hz
        goal = obs.target_index if self.goal is None else self.goal
        gx, gy, gz = obs.grasp_points[goal].tolist()  # where the object is now
        ee = obs.ee.tolist()
        if self._target is None:
            self._target = (ee[0], ee[1], ee[2])
        tx, ty, tz = self._target
        if goal in obs.lying:  # wait, out of the way, for it to be stood up again
            self._phase = "hover"
            self._stall_ref = None
            rise = float(obs.goal_positions[goal][2]) + self.approach_height
            return self._move(dt, (tx, ty, max(tz, rise)), grasp=False)
        stalled = self._stalled(obs.t, ee)
        hz = gz + self.approach_height  # hover point: above the grasp point
        if self._phase == "hover":
            near = math.hypot(ee[0] - gx, ee[1] - gy) < 0.015 and abs(ee[2] - hz) < 0.03
            if near or stalled:
                self._phase = "descend"
                self._stall_ref = None
                stalled = False
        grasp = False
        if self._phase == "descend" and not obs.gripper_closed:
            dist = math.dist(ee, (gx, gy, gz))
            close = dist < self.grasp_tolerance
            stuck = stalled and self.grasp_when_stalled and dist < self.stalled_grasp_radius
            if (close or stuck) and obs.t - self._last_grasp_t > self.retry_s:
                grasp = True
                self._last_grasp_t = obs.t
                self._stall_ref = None
        return self._move(dt, (gx, gy, hz if self._phase == "hover" else gz), grasp=grasp)

    def _move(self, dt: float, way: tuple[float, float, float], *, grasp: bool) -> TeleopCommand:
        """The noise-free target one step of ``speed dt`` nearer ``way``, plus the noise."""
        tx, ty, tz = self._target  # type: ignore[misc]
        sx, sy, sz = way[0] - tx, way[1] - ty, way[2] - tz
        dist = math.sqrt(sx * sx + sy * sy + sz * sz)
        reach = self.speed * dt
        if dist > reach:
            f = reach / dist
            sx, sy, sz = sx * f, sy * f, sz * f
        self._target = tx, ty, tz = tx + sx, ty + sy, tz + sz
        ox, oy, oz = self._offset
        if self.noise > 0:
            a, b = self._noise_factors(dt)
            nx, ny, nz = self._normals()
            self._offset = ox, oy, oz = (a * ox + b * nx, a * oy + b * ny, a * oz + b * nz)
        return TeleopCommand(np.array((tx + ox, ty + oy, tz + oz)), grasp)

    def _normals(self) -> tuple[float, float, float]:
        """The next three standard normal numbers of ``rng``: the very numbers of
        ``rng.standard_normal(3)`` each tick, drawn ``NOISE_BATCH`` at a time (one draw and one
        ``tolist`` per 256 ticks instead of per tick)."""
        drawn = self._drawn
        i = self._next_drawn
        if i == len(drawn):
            drawn = self._drawn = self.rng.standard_normal(NOISE_BATCH).tolist()
            i = 0
        self._next_drawn = i + 3
        return drawn[i], drawn[i + 1], drawn[i + 2]

    def _noise_factors(self, dt: float) -> tuple[float, float]:
        """Ornstein-Uhlenbeck step ``o' = a o + b n``: ``a = exp(-dt / tau)``,
        ``b = sqrt(1 - a^2) sigma`` (cached per ``dt``)."""
        cached = self._noise_cache
        if cached is None or cached[0] != dt:
            a = math.exp(-dt / self.noise_time_s)
            cached = self._noise_cache = (dt, a, math.sqrt(1 - a * a) * self.noise)
        return cached[1], cached[2]

    def _stalled(self, t: float, ee: list[float]) -> bool:
        """True when the TCP moved less than 5 mm during the last ``stall_s`` seconds."""
        ref = self._stall_ref
        if ref is not None and not math.dist(ee, ref[1]) > 0.005:
            return t - ref[0] >= self.stall_s
        self._stall_ref = (t, ee)
        return False


class IdleInput:
    """A user who never moves: the target stays where the gripper started."""

    def command(self, obs: TrialObservation) -> TeleopCommand:
        return TeleopCommand(obs.user_target, False)

"""A simulated participant's hand on the gizmo: an ``InputSource`` for one trial.

Each tick the user sets an absolute target (clamped by the interface's reach):

    target = clamp(r(t) + c + push + n)

- ``r``: a minimum-jerk plan from where the hand was to the aim point ``a`` (the target
  object's grasp point, later the lift point), ``T = a_F + b_F log2(1 + D / W)`` (see
  :mod:`study.simulated.movement`), progress ``dphi/dt = (1 - rho) w / T`` where
  ``w = clip(1 - (lag - dz) / wait_lag, 0, 1)``: the user waits for a robot that trails behind.
- ``c``: correction of what is seen. The user expects the gripper to trail their (reachable)
  plan like the unassisted robot (an internal forward model ``dm/dt = (clamp(r) - m) / lag``)
  and corrects the difference they see, ``e = m(t - tau) - ee(t - tau)``, split along the
  direction to ``a`` (see ``_seen_error``: a robot ahead is help, a robot behind but coming is
  slow, a robot across or stuck is corrected): ``dc/dt = k_eff dz(e_corr)`` with a dead zone
  ``dz`` and ``k_eff = min(k_max, k (1 + f) (1 - rho))``, leaking back to the plan with time
  constant ``leak`` (``- c / leak``: corrections fade once no longer needed); anti-windup
  keeps ``r + c + push`` inside the reach region (the gizmo stops at the reach).
- ``push``: steering against a robot that works against the goal, ``f`` and ``rho`` from
  :mod:`study.simulated.reaction` (everything seen is ``tau`` seconds old). Whether the robot
  is overriding them the user judges against a second forward model, of their own input
  (``dm_h/dt = (hand - m_h) / lag``), split the same way (a robot ahead is help).
- ``n``: Ornstein-Uhlenbeck hand noise, sd ``sigma (1 + careless rho)``.

Surprise (:mod:`study.simulated.surprise`): a gripper motion their forward model did not
predict stops the user's input (no plan progress, no corrections: the hand holds still) for a
re-planning time; then they plan afresh from where the hand is. Trust
(:mod:`study.simulated.trust`, carried across a participant's runs) falls with the robot's
errors as seen -- opposition, the gripper taken to the other object, knocks -- and scales how
far a relaxer relaxes and how fast the fight builds. While the target lies knocked over
(``obs.lying``) the user waits, hand raised above the table, until it stands again, then
approaches it anew.

Grasp (``grasp`` is held True from the request on; trials react to its rising edge): closes
when the seen gripper is within ``grasp_radius`` of ``a`` and slower than ``settle_speed``
(or, on an impatient "early" attempt, as soon as it is within ``early_radius``, still moving;
or once it stalls within ``stall_radius``; a gripper stalled within ``stall_radius`` of the
object itself but not of a misjudged aim makes them look again: a new attempt). Once the object is
seen in the gripper (after at least ``close_wait``) they lift by ``lift_m`` (harmless where the
trial lifts by itself); an empty gripper ``check_after`` after closing, or an object slipping
out, makes them open, pause and reach again with a fresh plan.

The user knows which object to pick up (``obs.target_index``, as participants are told "the
bottle") and sees the robot; they never read ``obs.alpha``, ``obs.predicted`` or conditions.

``goal_level=True`` (users of the page's gizmo or keys, :mod:`study.simulated.interface`): the
user has no free 3-D hand path; ``intent = clamp(a + c + push)`` is where they want the handle
next, the interface moves it there, and the expected gripper ``m`` trails the handle as it
really moved (``obs.user_target``), so only a robot that does not follow the handle is corrected.
"""

from __future__ import annotations

import math

import numpy as np

from app.teleop.reach import finite3
from app.teleop.types import TeleopCommand, TrialObservation
from study.simulated._vec import clamp_box, norm
from study.simulated.errors import ObservationError
from study.simulated.experience import ExperienceLog, RunExperience
from study.simulated.movement import HandNoise, fitts_time, minimum_jerk
from study.simulated.perception import DelayedView, Seen
from study.simulated.population import ParticipantParams
from study.simulated.reaction import Reaction
from study.simulated.surprise import Surprise
from study.simulated.trust import Trust

WAIT, REACH, CLOSE, LIFT, OPEN = "wait", "reach", "close", "lift", "open"


class SimulatedUser:
    """One participant's input for one trial (make a new one per trial).

    ``command(obs)`` implements ``app.teleop.InputSource``; ``experience(...)`` summarises the
    run for the questionnaire; ``phase``, ``reaction``, ``attempts`` are exposed for tests.
    """

    def __init__(
        self,
        params: ParticipantParams,
        *,
        rng: np.random.Generator,
        goal_level: bool = False,
        trust: Trust | None = None,
    ) -> None:
        self.params = params
        self.goal_level = goal_level
        self.rng = rng
        self.reaction = Reaction(params.reaction)
        self.surprise = Surprise(params.surprise, lag_s=params.motor.follow_lag_s, rng=rng)
        if trust is None:  # one run on its own
            trust = Trust(params.trust)
            trust.new_run()
        self.trust = trust
        self.noise = HandNoise(sd=params.motor.noise_sd_m, tau=params.motor.noise_tau_s, rng=rng)
        self.log = ExperienceLog()
        self.phase = WAIT
        self.attempts = 0
        self.grasp_closed = False
        self.seen_handle: np.ndarray | None = None  # the handle as seen tau ago
        self._view: DelayedView | None = None
        self._t_prev: float | None = None
        self._phase_t = 0.0
        self._r0 = np.zeros(3)
        self._aim = np.zeros(3)
        self._plan_t = 1.0
        self._phi = 0.0
        self._c = np.zeros(3)
        self._r = np.zeros(3)
        self._model = np.zeros(3)
        self._follow = np.zeros(3)
        self._hand = np.zeros(3)
        self._early = False
        self._best = self._best_across = math.inf
        self._best_t = self._best_across_t = 0.0
        self._stopped = False
        self._waiting = False
        self._held_since: float | None = None
        self._told_above = False  # read the notice: the gripper is held above the object

    @property
    def stopped(self) -> bool:
        """The user does not pursue the goal: re-planning after a surprise (``replanning``),
        or waiting for a knocked-over object to be stood up again (``waiting``)."""
        return self._stopped or self._waiting

    @property
    def replanning(self) -> bool:
        """Stopped to re-plan after a surprise: the hand holds still."""
        return self._stopped

    @property
    def waiting(self) -> bool:
        """Waiting, hand raised out of the way, for the target to be stood up again."""
        return self._waiting

    # ---- InputSource -----------------------------------------------------------------------
    def command(self, obs: TrialObservation) -> TeleopCommand:
        """Next target and gripper wish from the observation (see the module docstring)."""
        goal = self._goal(obs)  # where the object is now: a nudged object is re-aimed at
        if self._view is None:
            self._start(obs)
        assert self._view is not None
        lo, hi = obs.reach.lo, obs.reach.hi
        dt = 1.0 / obs.rate_hz if self._t_prev is None else max(obs.t - self._t_prev, 0.0)
        self._t_prev = obs.t
        own = np.array(obs.user_target, dtype=float)
        self._view.push(
            obs.t, np.array(obs.ee, dtype=float), obs.grasped, self._model, self._follow, own
        )
        seen = self._view.seen()
        self.seen_handle = seen.own
        target_name = obs.goal_names[obs.target_index]
        self._perceive(obs, dt, seen)
        self._read_notice(obs, goal)
        if not self.stopped:
            self._advance_phase(
                obs.t,
                seen_t=seen.t,
                ee=seen.ee,
                speed=norm(seen.velocity),
                grasped=seen.grasped,
                goal=goal,
                target_name=target_name,
            )

        self.log.add(t=obs.t, input_velocity=seen.own_velocity, robot_velocity=seen.velocity)
        if self.phase != WAIT:
            self._react(obs, dt, seen, own=own, goal=goal)
        scale = 1.0 + self.params.reaction.careless_noise_gain * self.reaction.relax
        target = clamp_box(self._hand + self.noise.step(dt, scale=scale), lo, hi)
        return TeleopCommand(target=target, grasp=self.grasp_closed)

    def _react(
        self, obs: TrialObservation, dt: float, seen: Seen, *, own: np.ndarray, goal: np.ndarray
    ) -> None:
        """Reaching or carrying: react to the robot (opposition, relaxing, trust), then move the
        hand along the plan with corrections (``_steer``) or hold it (stopped, waiting)."""
        m = self.params.motor
        hi = obs.reach.hi
        err, err_size, lag = self._seen_error(seen.plan, seen.ee, seen.velocity)
        aim, follow = self._aim, seen.follow
        if self._told_above:  # the page said why it stays up: over the middle first, then down
            err, err_size = np.zeros(3), 0.0
            aim, follow = np.array((aim[0], aim[1], seen.ee[2])), seen.ee
        trust = self.trust
        points = np.asarray(obs.grasp_points, dtype=float)
        self.reaction.update(
            dt=dt,
            velocity=seen.velocity,
            ee=seen.ee,
            aim=aim,
            own_target=seen.own,
            commanded=follow,
            deviation=self._overridden(follow, seen.ee, seen.velocity),
            trust=trust.level,
            fight_gain=trust.fight_gain,
        )
        trust.observe(
            dt,
            opposed=self.reaction.opposed,
            ee=seen.ee,
            handle=seen.own,
            others=[p for k, p in enumerate(points) if k != obs.target_index],
            knocks=obs.knocks,
        )
        rho = self.reaction.relax
        wait = min(max(1.0 - (lag - m.feedback_deadzone_m) / m.wait_lag_m, 0.0), 1.0)
        blend = 1.0 - math.exp(-dt / m.follow_lag_s)
        if self.goal_level:  # the interface moves the handle; the gripper should trail it
            self._model = self._model + blend * (own - self._model)
        if not self.stopped:  # a stopped hand holds still: no plan, no corrections
            self._steer(
                obs, dt, seen, own=own, err=err, err_size=err_size, rho=rho, wait=wait, blend=blend
            )
        elif self._waiting:  # out of the way: above where the object stood
            stood = float(obs.goal_positions[obs.target_index][2])
            rise = max(stood, float(goal[2])) + self.params.grasp.lift_m
            self._hand[2] = min(max(self._hand[2], rise), hi[2])
        shown = own if self.goal_level else self._hand  # the input the robot was given
        self._follow = self._follow + blend * (shown - self._follow)

    def _steer(
        self,
        obs: TrialObservation,
        dt: float,
        seen: Seen,
        *,
        own: np.ndarray,
        err: np.ndarray,
        err_size: float,
        rho: float,
        wait: float,
        blend: float,
    ) -> None:
        """The hand this tick: the plan ``r`` (minimum-jerk, slowed by relaxing and waiting; the
        aim itself at goal level) plus the correction ``c`` (``dc/dt = k (1 - dz/|e|) e`` outside
        the dead zone, leaking back), lined up above the object first, clamped to the reach
        (anti-windup)."""
        m = self.params.motor
        lo, hi = obs.reach.lo, obs.reach.hi
        if self.goal_level:
            self._r = self._aim
        else:
            self._phi = min(1.0, self._phi + dt * (1.0 - rho) * wait / self._plan_t)
            self._r = self._r0 + (self._aim - self._r0) * minimum_jerk(self._phi)
            self._model = self._model + blend * (clamp_box(self._r, lo, hi) - self._model)
        if err_size > m.feedback_deadzone_m:
            k = min(
                m.max_gain_per_s,
                m.feedback_gain_per_s * (1.0 + self.reaction.fight) * (1.0 - rho),
            )
            self._c = self._c + dt * k * (1.0 - m.feedback_deadzone_m / err_size) * err
        self._c = self._c * math.exp(-dt / m.correction_leak_s)
        hand = self._r + self._c + self.reaction.push_offset()
        if self.goal_level and self.phase == REACH and not self._lined_up(obs.t, seen.ee):
            hand[2] = max(hand[2], own[2])  # line up above the object before going down
        clamped = clamp_box(hand, lo, hi)
        self._c = self._c + (clamped - hand)  # anti-windup: the gizmo stops at the reach
        self._hand = clamped

    def _perceive(self, obs: TrialObservation, dt: float, seen: Seen) -> None:
        """Surprise and waiting: whether the user's input holds still this tick. A surprise
        (:mod:`study.simulated.surprise`) stops them while they reach (or wait to start); once
        the stop is over they plan afresh from where the hand is. A target lying knocked over
        makes them wait, hand raised, until it stands again; then they approach it anew."""
        was = self.stopped
        if self.phase in (WAIT, REACH):
            self._stopped = self.surprise.update(
                obs.t, dt, ee=seen.ee, velocity=seen.velocity, handle=seen.own
            )
        else:
            self._stopped = False
        lying = obs.target_index in obs.lying
        if self._waiting and not lying and self.phase == REACH:
            self._waiting = False
            self._new_attempt(self._goal(obs), obs.t)
        self._waiting = lying and self.phase == REACH
        if was and not self.stopped and self.phase == REACH:
            self._new_plan(self._aim)

    @property
    def intent(self) -> np.ndarray:
        """Where the user wants the handle now (clamped to the reach; no hand noise), (3,)."""
        return self._hand.copy()

    def experience(self, *, duration_s: float | None = None, success: bool) -> RunExperience:
        """What this run was like for the participant (the questionnaire's input)."""
        return self.log.finish(duration_s=duration_s, success=success)

    # ---- internals -------------------------------------------------------------------------
    def _seen_error(
        self, expected: np.ndarray, ee: np.ndarray, velocity: np.ndarray
    ) -> tuple[np.ndarray, float, float]:
        """Split the seen error ``e = m - ee`` by the direction ``d`` to the aim.

        Returns ``(e_corr, deviation, lag)``. Along ``d``: the robot ahead (``e.d < 0``) is help
        and ignored; behind but moving toward the aim (``v.d > v_min``) it is merely slow: that
        ``lag`` slows the user's plan but is not corrected; behind and not progressing, it is
        stuck or pulled away and corrected. Across ``d``: always corrected. ``deviation`` is the
        size of the corrected part (what counts as opposition).
        """
        err = expected - ee
        to_aim = self._aim - ee
        dist = norm(to_aim)
        if dist < 1e-9:
            return err, norm(err), 0.0
        if self.goal_level and dist <= norm(self._aim - expected):
            return np.zeros(3), 0.0, 0.0  # nearer the aim than the handle put it: help
        d = to_aim / dist
        along = float(err @ d)
        lag = 0.0
        if along < 0.0 or float(velocity @ d) > self.params.reaction.opposition_speed_m_s:
            err = err - along * d
            lag = max(along, 0.0)
        return err, norm(err), lag

    def _overridden(self, commanded: np.ndarray, ee: np.ndarray, velocity: np.ndarray) -> float:
        """How far the robot is from where the user's input should have put it, not counting
        a robot ahead toward the aim (help) or one on its way there (moving within the
        opposition angle of the commanded point)."""
        err = commanded - ee
        to_aim = self._aim - ee
        dist = norm(to_aim)
        if dist > 1e-9:
            along = float(err @ to_aim) / dist
            if along < 0.0:
                err = err - (along / dist) * to_aim
        gap = norm(err)
        speed = norm(velocity)
        r = self.params.reaction
        coming = (
            gap > 1e-9
            and speed > r.opposition_speed_m_s
            and float(velocity @ err) / (speed * gap)
            > math.cos(math.radians(r.opposition_angle_deg))
        )
        if coming:
            return 0.0  # on its way: slow, not overriding
        return gap

    def _lined_up(self, t: float, ee: np.ndarray) -> bool:
        """True once the seen gripper is within ``grasp_radius`` of the aim across the table
        (the open fingers then clear the object on the way down), or has stopped getting
        nearer across for ``stall_time`` (it will not line up better: go down anyway), or the
        user is fighting the robot (then they steer, they do not wait)."""
        g = self.params.grasp
        across = math.hypot(self._aim[0] - ee[0], self._aim[1] - ee[1])
        if across < self._best_across - 0.003:
            self._best_across, self._best_across_t = across, t
        if self.reaction.fight > 0.5:  # steering against the robot, not waiting for it
            return True
        return across < g.grasp_radius_m or t - self._best_across_t > g.stall_time_s

    def _goal(self, obs: TrialObservation) -> np.ndarray:
        positions = np.asarray(obs.grasp_points, dtype=float)
        if not 0 <= obs.target_index < len(positions):
            raise ObservationError(
                f"target_index {obs.target_index} does not index the {len(positions)} goals"
                f" {list(obs.goal_names)}; the trial must say which object to pick up"
            )
        goal = positions[obs.target_index]
        if not finite3(goal):
            raise ObservationError(f"target grasp point must be a finite 3-vector, got {goal}")
        return goal

    def _start(self, obs: TrialObservation) -> None:
        self._view = DelayedView(tau=self.params.motor.reaction_delay_s, rate_hz=obs.rate_hz)
        start = np.asarray(obs.user_target, dtype=float)
        if not finite3(start):
            start = np.asarray(obs.ee, dtype=float)
        self._hand = start.copy()
        self._r = start.copy()
        self._r0 = start.copy()
        self._model = start.copy()
        self._follow = start.copy()

    def _new_plan(self, aim: np.ndarray) -> None:
        m = self.params.motor
        self._r0 = self._hand.copy()
        self._c = np.zeros(3)
        self._r = self._r0.copy()
        self._aim = aim
        self._phi = 0.0
        dist = norm(aim - self._r0)
        self._plan_t = max(
            fitts_time(dist, a=m.fitts_a_s, b=m.fitts_b_s_per_bit, width=m.fitts_width_m), 1e-3
        )

    def _read_notice(self, obs: TrialObservation, goal: np.ndarray) -> None:
        """The open gripper held above the object they reach for (``obs.held_above``: the page
        says it would come down on the object and asks to centre it first): ``notice_read_s``
        after it began, and again as long as it lasts, they aim afresh at the object's middle;
        knowing why the gripper stays up, they stop fighting it and no longer correct its
        height: they take it over the object's middle (``_react``)."""
        if obs.held_above != obs.target_index or self.phase != REACH or self.stopped:
            self._held_since = None
            self._told_above = False
            return
        if self._held_since is None:
            self._held_since = obs.t
        elif obs.t - self._held_since >= self.params.grasp.notice_read_s:
            self._held_since = obs.t
            self._told_above = True
            self.reaction.calm()  # the robot was not fighting them: it said what to do
            self._new_attempt(goal, obs.t, careful=True)

    def _new_attempt(self, goal: np.ndarray, t: float, *, careful: bool = False) -> None:
        """A new reach for ``goal``; it may be impatient, and unless ``careful`` (told where to
        go) it may misjudge depth."""
        g = self.params.grasp
        self.attempts += 1
        self._early = bool(self.rng.random() < g.early_grasp_p)
        offset = np.zeros(3)
        if self.rng.random() < g.miss_p and not careful:  # misjudged depth: aims beside it
            angle = self.rng.uniform(0.0, 2.0 * math.pi)
            offset[:2] = g.miss_offset_m * np.array([math.cos(angle), math.sin(angle)])
        self._best = self._best_across = math.inf
        self._best_t = self._best_across_t = t
        self._new_plan(goal + offset)

    def _advance_phase(
        self,
        t: float,
        *,
        seen_t: float,
        ee: np.ndarray,
        speed: float,
        grasped: str | None,
        goal: np.ndarray,
        target_name: str,
    ) -> None:
        g = self.params.grasp
        since = t - self._phase_t
        if self.phase == WAIT:
            if t >= self.params.motor.reaction_delay_s:
                self._enter(REACH, t)
                self._new_attempt(goal, t)
            return
        if self.phase == REACH:
            dist = norm(self._aim - ee)
            if dist < self._best - 0.003:
                self._best, self._best_t = dist, t
            settled = dist < g.grasp_radius_m and speed < g.settle_speed_m_s
            impatient = self._early and dist < g.early_radius_m  # closes while still moving
            still = t - self._best_t > g.stall_time_s
            stalled = dist < g.stall_radius_m and still
            if settled or impatient or stalled:
                self.grasp_closed = True
                self._enter(CLOSE, t)
            elif still and norm(goal - ee) < g.stall_radius_m:
                # stopped at the object but not where they aimed (a misjudged depth the
                # gripper will not follow, e.g. past the reach): they look again
                self._new_attempt(goal, t)
        elif self.phase == CLOSE:
            if grasped == target_name and since >= g.close_wait_s:
                self._enter(LIFT, t)
                self._new_plan(self._aim + np.array([0.0, 0.0, g.lift_m]))
            elif since >= g.check_after_s and grasped != target_name:
                self._release(t)  # nothing (or the wrong thing) in the gripper: open, retry
        elif self.phase == LIFT and grasped != target_name and seen_t >= self._phase_t:
            self._release(t)  # slipped out
        elif self.phase == OPEN and since >= g.retry_pause_s:
            self._enter(REACH, t)
            self._new_attempt(goal, t)

    def _release(self, t: float) -> None:
        self.grasp_closed = False
        self._enter(OPEN, t)

    def _enter(self, phase: str, t: float) -> None:
        self.phase = phase
        self._phase_t = t

"""One trial: input source -> user target -> U (IK) -> blending -> robot, tick by tick.

Each ``tick()`` asks the input source for a target, clamps it to the reach region, turns it
into ``U`` with a velocity-limited IK step, blends ``U`` with the policy's ``P`` (prediction
from the user target, confidence ``c = max(0, 1 - d / D)``, arbitration ``alpha(c)``), servos
the arm to ``(1 - alpha) U + alpha P`` and advances the physics (with the study's components
``U``, ``P`` and the command come from one compiled call: ``app.trial.fused_control``). What the ticks mean is the
trial's task (``app.trial.tasks``; by default :class:`~app.trial.tasks.lift.LiftTask`): a grasp
request closes the gripper in physics; holding an object, the arm lifts it by itself; the trial
succeeds when the target is ``lift_height_m`` above its rest height. Outcomes (``app.trial.records.OUTCOMES``):
``success``, ``wrong_object``, ``timeout``, ``aborted`` and ``interrupted``; and the
accidents, each with its own event: a held object that falls out of the gripper (``dropped``),
an object knocked over (``knocked_over``) or pushed off the table (``pushed_off``). Under
``on_knock = "reset"`` (the default) no accident ends the run: the gripper opens after a drop,
and a knocked, fallen or dropped object is put back at its start pose once it has settled
(``app.trial.accidents``), while the run and its clock go on (meanwhile a robot whose
predicted goal lies holds back, alpha = 0: it would take the gripper to the very place the
object must be stood up in, and its own hand would keep it lying); under ``"end"`` the first
accident ends it with that outcome. Outcomes are logged, never raised. The arm's touches on
objects are logged as events at the tick they start and end (``app.trial.contacts``).

Thread safety: ``tick``, ``pause``, ``resume``, ``abort`` and ``interrupt`` take one lock; the
server runs ``tick`` paced in its own thread while UI callbacks feed the input source.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from app.blending import moved_goals, reach_below
from app.robot.errors import PhysicsError
from app.robot.scene import Scene, build_scene
from app.robot.simulation import BodyPoses, Simulation
from app.teleop.guarded_descent import DescentGuard
from app.teleop.ik_step import IKStep
from app.teleop.types import InputSource, TeleopCommand, TrialObservation
from app.trial.accidents import Accidents
from app.trial.build_blender import build_blender
from app.trial.config import TrialConfig
from app.trial.contacts import ContactLog
from app.trial.events import EventKind, TrialEvent, mark
from app.trial.fused_control import fused_control
from app.trial.records import BlendTick, TickRecord, TrialResult
from app.trial.steering import Steering
from app.trial.tasks import LiftTask, Task

FAR_OUTSIDE_M = 0.5  # a raw target this far outside the reach region is logged as such
_FLOAT = np.dtype(float)
GOAL_MOVED_M = 0.005  # a goal follows its object once the object has moved this far from it
_LOST = (EventKind.DROPPED, EventKind.LIFT_FAILED)  # the task let go of what it held
_CLAMPED = mark(EventKind.TARGET_CLAMPED)  # most ticks of a Hard task log one: shared
_FAR_OUTSIDE = mark(EventKind.TARGET_FAR_OUTSIDE)


class Trial:
    """A trial drivable tick by tick (``tick()``) or to the end (``run_trial``); ``task``: what
    the ticks mean (a fresh :class:`~app.trial.tasks.lift.LiftTask` when ``None``).

    ``keep_records=False``: ``records`` and ``events`` stay empty (``tick()`` still returns each
    record), for a caller that keeps every tick itself -- a study session writes each one to its
    store; kept here as well, a served trial held about 1.5 kB and one more object for the
    garbage collector to walk per tick (``benchmarks/server_memory.py``)."""

    def __init__(
        self,
        config: TrialConfig,
        input_source: InputSource,
        *,
        seed: int = 0,
        scene: Scene | None = None,
        task: Task | None = None,
        keep_records: bool = True,
    ) -> None:
        self.config = config
        self.keep_records = keep_records
        self._dt = config.dt
        self._rate_hz = config.rate_hz
        self._time_limit = config.time_limit_s - 1e-9
        self._substeps = config.substeps
        self.input_source = input_source
        self.seed = seed
        self.scene = scene if scene is not None else build_scene(config.scene)
        self.sim = Simulation(self.scene, physics_dt=config.physics_dt)
        kin = self.scene.arm.kinematics.copy()
        self.kinematics = kin
        self.ik = IKStep(kin, rate_hz=config.rate_hz, posture=self.scene.start_q)
        self.blender = build_blender(config, self.scene, kin)
        self.blender.reset(self.scene.start_ee)
        self.fused = fused_control(self.ik, self.blender)
        """``U``, ``P`` and the command in one compiled call (``app.trial.fused_control``), or
        ``None``: the components' own calls (a configuration other than the study's)."""
        self._lock = threading.RLock()
        self._paused = False
        self._pause_events: list[TrialEvent] = []
        self.ticks = 0
        self.outcome: str | None = None
        self._grasp_prev = False
        self.contacts = ContactLog(self.scene.object_names)
        self.accidents = Accidents(self.sim, self.scene.object_names, on_knock=config.on_knock)
        n = len(self.scene.goals)
        self.user_target = self.scene.start_ee.copy()
        self.user_input = self.user_target  # what the prediction reads: the path, or the target
        reach = self.scene.reach
        self._reach_box = (tuple(reach.lo.tolist()), tuple(reach.hi.tolist()))
        # the state after the last physics step (fresh arrays each tick, never written to):
        # read once per tick, shared by the next observation, the control step and the record
        self._q = self.sim.q
        self._ee = self.sim.ee
        self._object_positions = self.sim.object_positions()
        self._objects_key: tuple[bytes, object] = (b"", None)  # what they were refreshed from
        self._grasp_points = self.scene.goals.positions
        # the goals over GOAL_MOVED_M off their grasp points, and the arrays that told it
        # (neither is written to: a change is a new array)
        self._far_seen: tuple[object, object, list[int]] = (None, None, [])
        self.steering = Steering(
            self.scene, reach_below=reach_below(self.scene.hand), floor=self._reach_box[0][2]
        )
        """Where ``U`` steers the open hand around the objects (``app.trial.steering``)."""
        self.grasp_offset = 0.0
        """The open hand's offset (m, world x) from the middle of the object it was down
        around at the last grasp request (its palm over it, the TCP below its top), when more
        than ``CENTRED_M`` along the slot, else 0: why such a grasp misses or slips (the page
        says so, and which way to move)."""
        self._blend = BlendTick(0.0, 0.0, np.full(n, 1.0 / n), -1, 0.0, math.nan)
        self.records: list[TickRecord] = []
        self.events: list[tuple[float, TrialEvent]] = []
        self.task: Task = LiftTask() if task is None else task
        self.task.start(self)

    # ---- state -------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Simulated time, seconds (pauses excluded)."""
        return self.ticks * self._dt

    @property
    def done(self) -> bool:
        return self.outcome is not None

    @property
    def paused(self) -> bool:
        return self._paused

    @property
    def blend(self) -> BlendTick:
        """What the blender gave at the last tick it ran (as applied; see ``BlendTick``)."""
        return self._blend

    @property
    def success(self) -> bool:
        return self.outcome == "success"

    @property
    def guard(self) -> DescentGuard:
        """The open hand's descent guard (``app.teleop.guarded_descent``)."""
        return self.steering.guard

    @property
    def held_above(self) -> int | None:
        """The object the open hand is held above (``app.teleop.guarded_descent``), or ``None``."""
        return self.steering.guard.held

    @property
    def resting_on(self) -> int | None:
        """The object the open hand rests on this tick (``Steering.resting_on``), or ``None``."""
        return self.steering.resting_on

    @property
    def resting_centred(self) -> bool:
        """Whether the hand is then centred on it along the slot (``CENTRED_M``)."""
        return self.steering.resting_centred

    @property
    def resting_offset(self) -> float:
        """The hand's offset then (m, world x) from that object's middle."""
        return self.steering.resting_offset

    def poses(self) -> BodyPoses:
        """The scene's body poses and the gripper now (copies, for a renderer's thread)."""
        return self.sim.poses()

    def pause(self) -> None:
        with self._lock:
            if not self._paused and not self.done:
                self._paused = True
                self._pause_events.append(TrialEvent(EventKind.PAUSED))

    def resume(self) -> None:
        with self._lock:
            if self._paused:
                self._paused = False
                self._pause_events.append(TrialEvent(EventKind.RESUMED))

    def abort(self, outcome: str = "aborted") -> None:
        """End the trial now (experimenter: ``aborted``; lost participant: ``interrupted``)."""
        if outcome not in ("aborted", "interrupted"):
            raise ValueError(f"outcome: 'aborted' or 'interrupted', got {outcome!r}")
        with self._lock:
            if not self.done:
                self._finish(outcome, [TrialEvent(EventKind(outcome))])

    def interrupt(self) -> None:
        self.abort("interrupted")

    def observation(self) -> TrialObservation:
        """What an input source sees now (consistent: taken under the trial's lock)."""
        with self._lock:
            return self._observation()

    def _observation(self) -> TrialObservation:
        blend = self._blend
        task, scene, accidents = self.task, self.scene, self.accidents
        held = task.held
        return TrialObservation(
            self.ticks * self._dt,
            self._q,  # fresh arrays each tick, never written to: shared, not copied
            self._ee,
            task.gripper_closed,
            self.user_target,
            scene.reach,
            scene.goals.names,
            self.blender.goals.positions,
            scene.target_index,
            blend.alpha,
            blend.predicted,
            None if held is None else scene.object_names[held],
            self._rate_hz,
            self._object_positions,
            self._grasp_points,
            accidents.count,
            accidents.down,
            self.steering.guard.held,
        )

    def _objects_moved(self) -> None:
        """Refresh the objects' positions and the grasp points that move with them (kept as
        they are when no object moved since the last refresh: resting objects sleep, so most
        ticks see the very same positions)."""
        pos = self.sim.object_positions()
        key = (pos.tobytes(), self.sim.rest_positions)
        if key[0] == self._objects_key[0] and key[1] is self._objects_key[1]:
            return
        self._objects_key = key
        self._object_positions = pos
        self._grasp_points = self.scene.goals.positions + (pos - self.sim.rest_positions)
        self.steering.objects_moved(self._grasp_points)

    def _follow_objects(self, events: list[TrialEvent]) -> None:
        """Re-aim the robot at objects a grasp moved: ``G_k <-`` object ``k``'s grasp point now,
        with its grasp configuration by IK from the old one, once ``G_k`` is ``GOAL_MOVED_M``
        off. Each move is logged (a ``goal_moved`` event with the new position) at the tick it
        takes effect, so a replay can apply it. A knocked-over object keeps its goal (no
        top-down grasp there) until it is stood up again.
        """
        goals = self.blender.goals
        points, seen = self._grasp_points, self._far_seen
        if points is seen[0] and goals.positions is seen[1]:  # nothing moved since last time
            far = seen[2]
        else:
            off = np.linalg.norm(points - goals.positions, axis=1)
            far = np.flatnonzero(off > GOAL_MOVED_M).tolist()
            self._far_seen = (points, goals.positions, far)
        moves = {}
        for k in far:
            if self.accidents.lying(k):
                continue
            position = self._grasp_points[k].copy()
            q0 = goals.configurations[k] if goals.configurations is not None else self._q
            solved = self.kinematics.ik(
                position,
                rotation=self.scene.grasp_rotations[k],
                q0=q0,
                posture=self.scene.start_q,
                tol=5e-4,
                rot_tol=5e-3,
            )
            moves[k] = (position, solved.q)
            events.append(
                TrialEvent(EventKind.GOAL_MOVED, obj=goals.names[k], position=tuple(position))
            )
        if moves:
            self.blender.set_goals(moved_goals(goals, moves))

    def result(self) -> TrialResult:
        return TrialResult(
            outcome=self.outcome or "interrupted",
            success=self.success,
            duration_s=self.t,
            ticks=self.ticks,
            records=tuple(self.records),
            goal_names=self.scene.goals.names,
            target=self.scene.target,
            seed=self.seed,
            task=self.config.task,
            mode=self.config.mode,
            events=tuple(self.events),
        )

    # ---- the loop ----------------------------------------------------------------------
    def run(self, *, realtime: bool = False) -> TrialResult:
        """Tick to the end, as fast as possible or paced to wall-clock time (pauses honoured)."""
        dt = self.config.dt
        start = time.perf_counter() - self.ticks * dt
        while not self.done:
            if self._paused:
                time.sleep(0.005)
                start = time.perf_counter() - self.ticks * dt
                continue
            self.tick()
            if realtime:
                delay = start + self.ticks * dt - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
        return self.result()

    def tick(self) -> TickRecord | None:
        """Advance one control period; ``None`` (nothing happens) while paused or once done."""
        with self._lock:
            if self._paused or self.done:
                return None
            events: list[TrialEvent] = self._pause_events
            self._pause_events = []
            q = self._q
            if self.sim.objects_live and self.task.reaching and self.ticks % 10 == 0:
                self._follow_objects(events)
            cmd = self._ask_input(events)
            self._set_user_target(cmd, events)
            request = cmd.grasp and not self._grasp_prev
            self._grasp_prev = bool(cmd.grasp)
            u, p, command = self._control(q, request, events)
            try:
                self.sim.step(
                    command,
                    gripper_closed=self.task.gripper_closed,
                    substeps=self._substeps,
                )
            except PhysicsError as exc:  # pragma: no cover - guarded by clipping
                events.append(TrialEvent(EventKind.PHYSICS_ERROR, text=str(exc)))
                self.ticks += 1
                self._q = self.sim.q
                self._ee = self.sim.ee
                self._finish("aborted", events)
                return self._record(q, q, q, events)
            self.ticks += 1
            sim = self.sim
            self._q = sim.q
            self._ee = sim.ee
            if sim.objects_live:
                self._objects_moved()
                events.extend(
                    self.contacts.update(
                        sim.arm_contacts(),
                        dt=self._dt,
                        grasping=self.task.gripper_closed,
                        held=self.task.held,
                    )
                )
            t = self.ticks * self._dt
            self._judge(events, t)
            if self.outcome is None and t >= self._time_limit:
                self._finish("timeout", events)
            return self._record(u, p, command, events)

    def _ask_input(self, events: list[TrialEvent]) -> TeleopCommand:
        try:
            return self.input_source.command(self._observation())
        except Exception as exc:  # an input device must never stop the loop
            events.append(TrialEvent(EventKind.INPUT_ERROR, text=type(exc).__name__))
            return TeleopCommand(self.user_target.copy(), False)

    def _set_user_target(self, cmd: TeleopCommand, events: list[TrialEvent]) -> None:
        target, outside = self._clamped(cmd.target)
        if target is None:
            events.append(mark(EventKind.INVALID_TARGET))
            return
        if outside > 0.0:
            events.append(_FAR_OUTSIDE if outside > FAR_OUTSIDE_M else _CLAMPED)
        self.user_target = target
        path = None if cmd.path is None else self._clamped(cmd.path)[0]
        if cmd.path is not None and path is None:
            events.append(mark(EventKind.INVALID_TARGET))
        self.user_input = target if path is None else path

    def _clamped(self, value: object) -> tuple[np.ndarray | None, float]:
        """``value`` clamped to the reach box and how far outside it was; ``None`` if it is not
        three finite numbers."""
        if type(value) is np.ndarray and value.dtype == _FLOAT and value.ndim == 1:
            raw = value.tolist()  # the usual input: no conversion needed
        else:
            try:
                raw = np.asarray(value, dtype=float).reshape(-1).tolist()
            except (TypeError, ValueError):
                raw = []
        if len(raw) != 3 or not math.isfinite(raw[0] + raw[1] + raw[2]):
            return None, 0.0
        # clamp to the reach box in scalars (three numbers: cheaper than array operations)
        x, y, z = raw
        (lx, ly, lz), (hx, hy, hz) = self._reach_box
        cx = lx if x < lx else (hx if x > hx else x)
        cy = ly if y < ly else (hy if y > hy else y)
        cz = lz if z < lz else (hz if z > hz else z)
        outside = math.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2)
        return np.array((cx, cy, cz)), outside

    def _control(
        self, q: np.ndarray, request: bool, events: list[TrialEvent]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(U, P, command)`` this tick: the task's command when it drives the arm, else the
        user's ``U`` blended with the policy's ``P``."""
        if request and self.task.reaching:
            self.grasp_offset = self.steering.offset(self._ee, self.accidents.fallen)
        held = self.task.control(q, self.t, request=request, events=events)
        if held is not None:  # the task drives the arm: the open hand rests on nothing
            steering = self.steering
            steering.resting_on, steering.resting_centred = None, False
            return held, held, held
        if self.task.gripper_closed:
            self.steering.closed()
            target = self.user_target
        else:
            blend = self._blend
            target = self.steering.steer(
                self._ee,
                self.user_target,
                blend.predicted if blend.alpha > 0.0 else -1,
                self.accidents.fallen,
                self.ticks * self._dt,
            )
        fused = self.fused
        if fused is not None and fused.ik is self.ik:
            u, rec = fused.step(q, target, x=self.user_input, robot_x=self._ee)
        else:
            u = self.ik(q, target)
            rec = self.blender.step(q, u, x=self.user_input, robot_x=self._ee)
        alpha, command, predicted = float(rec.alpha), rec.command, int(rec.predicted)
        if self.accidents.lying(predicted):  # its goal lies, to be stood up where the robot
            alpha, command = 0.0, u  # would take the gripper: it holds back meanwhile
        self._blend = BlendTick(  # Python numbers, as the tick record stores them
            alpha,
            float(rec.confidence),
            rec.probabilities,
            predicted,
            float(rec.motion_agreement),
            float(rec.rationality),
        )
        return u, rec.P, command

    def _judge(self, events: list[TrialEvent], t: float) -> None:
        """The task's verdict at time ``t`` (now), then every tenth tick the objects (knocked,
        fallen, stood up)."""
        task = self.task
        held = task.held
        outcome = task.judge(t, events)
        if outcome is not None:
            self._finish(outcome, events)
            return
        if held is not None and task.held is None and any(e.kind in _LOST for e in events):
            self.accidents.slipped(held, t)  # put back, as a knocked object is
        if self.ticks % 10 == 0:
            held = task.held if task.gripper_closed else None
            found, outcome = self.accidents.check(t, held=held)
            if found:
                events.extend(found)
                self._objects_moved()  # an object stood up again is seen where it stands
            if outcome is not None:
                self._finish(outcome, events)

    def _finish(self, outcome: str, events: list[TrialEvent]) -> None:
        if outcome == "timeout":
            events.append(TrialEvent(EventKind.TIMEOUT))
        self.outcome = outcome
        self.task.stop()
        events.extend(self.contacts.close())
        events.append(TrialEvent(EventKind.OUTCOME, text=outcome))

    def _record(
        self, u: np.ndarray, p: np.ndarray, command: np.ndarray, events: list[TrialEvent]
    ) -> TickRecord:
        blend = self._blend  # Python floats and ints (``_control``)
        if self.task.reaching:
            alpha, motion, rationality = blend.alpha, blend.motion_agreement, blend.rationality
        else:
            alpha, motion, rationality = 0.0, 0.0, math.nan
        t = self.ticks * self._dt
        if events and self.keep_records:
            self.events += [(t, e) for e in events]
        # u, p, command, probabilities and user_target are fresh arrays each tick (or the
        # unchanging hold configuration), never written to afterwards: no copies needed.
        rec = TickRecord(
            self.ticks,
            t,
            self._q,
            u,
            p,
            command,
            alpha,
            blend.confidence,
            blend.probabilities,
            blend.predicted,
            self.user_input,
            self._ee,
            self.sim.gripper_opening,
            tuple(events),
            motion,
            rationality,
        )
        if self.keep_records:
            self.records.append(rec)
        return rec


def run_trial(
    config: TrialConfig,
    input_source: InputSource,
    *,
    seed: int = 0,
    realtime: bool = False,
    scene: Scene | None = None,
    task: Task | None = None,
) -> TrialResult:
    """Run one trial to its end, as fast as possible or paced to wall-clock time."""
    return Trial(config, input_source, seed=seed, scene=scene, task=task).run(realtime=realtime)

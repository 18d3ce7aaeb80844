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
from app.blending.policy_grasp import HandLayer
from app.robot.errors import PhysicsError
from app.robot.scene import Scene, build_scene
from app.robot.simulation import BodyPoses, Simulation
from app.teleop.guarded_descent import CENTRED_M, DescentGuard, Footprint
from app.teleop.ik_step import IKStep
from app.teleop.lift_out import CLEARANCE_M, Cylinder, lift_out
from app.teleop.steer_core import CHANGED as STEER_CHANGED
from app.teleop.steer_core import STEERED, pack_consts, steer
from app.teleop.types import InputSource, TeleopCommand, TrialObservation
from app.trial.accidents import Accidents
from app.trial.build_blender import build_blender
from app.trial.config import TrialConfig
from app.trial.contacts import ContactLog
from app.trial.events import EventKind, TrialEvent, mark
from app.trial.fused_control import fused_control
from app.trial.records import BlendTick, TickRecord, TrialResult
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
        self._reach_below = reach_below(self.scene.hand)
        self._half_widths = tuple(o.grasp_width / 2 for o in self.scene.spec.objects)
        self.guard = _descent_guard(self.scene, self._reach_below)
        """Holds the open hand above an object it would come down on (``held_above``) and
        stops it, lowered around one, with its palm just over the top."""
        self.resting_on: int | None = None
        """The object around (or beside, under the palm) which the open hand is as low as it
        goes this tick, the input asking it lower (the guard's palm stop, or the reach's
        floor), or ``None``."""
        self.resting_centred = False
        """Whether the hand is then centred on that object along the slot (``CENTRED_M``)."""
        self.resting_offset = 0.0
        """The hand's offset then (m, world x) from that object's middle."""
        self.grasp_offset = 0.0
        """The open hand's offset (m, world x) from the middle of the object it was down
        around at the last grasp request (its palm over it, the TCP below its top), when more
        than ``CENTRED_M`` along the slot, else 0: why such a grasp misses or slips (the page
        says so, and which way to move)."""
        self._last_ee_z = math.inf  # the TCP's height at the last tick (``_note_resting``)
        self._cylinders = self._object_cylinders()
        self._footprints = self._object_footprints()
        self._start_steering()
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
            self.guard.held,
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
        self._cylinders = self._object_cylinders()
        self._footprints = self._object_footprints()
        self._footprint_rows = _rows(self._footprints)

    def _start_steering(self) -> None:
        """What the compiled steering (``_steer_compiled``) keeps between ticks."""
        self._footprint_rows = _rows(self._footprints)
        self._steer_consts = self._steering_constants()
        """``steer_core.steer``'s fixed numbers, or ``None``: the reference steers."""
        self._steer_state = np.array((*self.guard.state(), self._last_ee_z))  # (STATE)
        self._steer_synced = True  # whether _steer_state holds the guard's state
        self._steer_out = np.zeros(6)
        self._fallen_seen: tuple[int, ...] | None = None
        self._fallen = np.zeros(0, dtype=np.int64)  # the fallen objects' indices

    def _steering_constants(self) -> np.ndarray | None:
        """The numbers ``steer_core.steer`` steers by (the guard's hand, the reach's floor),
        or ``None`` when the lift-out rule's would differ from the guard's."""
        guard = self.guard
        same = (guard.reach_below, guard.slot, guard.clearance) == (
            self._reach_below,
            self.scene.spec.gripper_open,
            CLEARANCE_M,
        )
        if not same:  # pragma: no cover - one hand for both (``_descent_guard``)
            return None
        return pack_consts(
            reach_below=guard.reach_below,
            slot=guard.slot,
            clearance=guard.clearance,
            palm_above=guard.palm_above,
            palm_half=guard.palm_half,
            parts=guard.parts,
            parts_lo=min((lo for lo, _, _ in guard.parts), default=math.inf),
            low=guard.low,
            floor=self._reach_box[0][2],
        )

    def _object_footprints(self) -> tuple[Footprint, ...]:
        """Each object's cylinder with its half-width across the slot
        (``app.teleop.guarded_descent``)."""
        return tuple((*c, w) for c, w in zip(self._cylinders, self._half_widths, strict=True))

    def _object_cylinders(self) -> tuple[Cylinder, ...]:
        """Each object as ``(x, y, radius, top)`` where it stands now (``app.teleop.lift_out``)."""
        envelopes = self.scene.goals.envelopes
        if envelopes is None:
            return ()
        return tuple(
            (g[0], g[1], env[0], g[2] + env[1])
            for g, env in zip(self._grasp_points.tolist(), envelopes.tolist(), strict=True)
        )

    def _steer(self) -> np.ndarray:
        """Where ``U`` steers this tick: the user's target, or first out of an object the open
        hand is around and the target leaves (``app.teleop.lift_out``), or held above an object
        the open hand would come down on rather than around (``app.teleop.guarded_descent``;
        ``held_above`` names it), or no lower than its palm clears the top of an object it is
        lowered around (``resting_on`` names it). Not out of (or above) a lying
        object, nor out of the one the robot is taking the hand to (``alpha > 0`` at the last
        tick): its policy keeps the hand clear there, and in a Hard task the user's target,
        held at the reach's edge, always lies off the object the robot is carrying the hand to.
        In one compiled call (``app.teleop.steer_core``) when the hand's numbers allow it,
        else by :meth:`_steer_reference`, the reference the compiled call is tested equal to."""
        self.resting_on, self.resting_centred = None, False
        if self.task.gripper_closed:
            self.guard.release()
            self._steer_synced = False
            return self.user_target
        if self._steer_consts is None:
            return self._steer_reference()
        return self._steer_compiled(self._steer_consts)

    def _steer_compiled(self, consts: np.ndarray) -> np.ndarray:
        """:meth:`_steer_reference` as one call of ``steer_core.steer`` (the guard's state
        mirrored into it, and back when it changes)."""
        state = self._steer_state
        guard = self.guard
        if not self._steer_synced:  # the guard was released, or is new: take its state
            state[:7] = guard.state()
            self._steer_synced = True
        blend = self._blend
        fallen = self.accidents.fallen
        if fallen is not self._fallen_seen:
            self._fallen_seen = fallen
            self._fallen = np.array(fallen, dtype=np.int64)
        out = self._steer_out
        flags = steer(
            self._ee,
            self.user_target,
            self._footprint_rows,
            blend.predicted if blend.alpha > 0.0 else -1,
            self._fallen,
            state,
            out,
            consts,
            self.ticks * self._dt,
        )
        if flags & STEER_CHANGED:
            guard.set_state(state.tolist())
        x, y, z, resting, centred, offset = out.tolist()
        if resting >= 0.0:
            self.resting_on = int(resting)
            self.resting_centred = centred > 0.0
            self.resting_offset = offset
        return np.array((x, y, z)) if flags & STEERED else self.user_target

    def _steer_reference(self) -> np.ndarray:
        """:meth:`_steer` for an open gripper in Python: the reference."""
        guard = self.guard
        taking = self._blend.predicted if self._blend.alpha > 0.0 else -1
        skip = (taking, *self.accidents.fallen)  # a dropped object still stands: guarded
        ee, target = self._ee.tolist(), self.user_target.tolist()
        t = self.ticks * self._dt
        if guard.held is not None:  # a hold is kept until the guard lets go (its docstring)
            hold = guard.steer(ee, target, self._footprints, now=t, skip=skip)
            if hold is not None:
                return np.array(hold)
        out = lift_out(
            ee,
            target,
            self._cylinders,
            reach_below=self._reach_below,
            slot=self.scene.spec.gripper_open,
            skip=skip,
        )
        if out is not None:
            return np.array(out)
        hold = guard.steer(ee, target, self._footprints, now=t, skip=skip)
        if hold is not None:
            return np.array(hold)
        rest = guard.rest(ee, target, self._footprints, skip=skip)
        self._note_resting(ee, target[2], rest)
        return self.user_target if rest is None else np.array(rest[0])

    def _note_resting(
        self, ee: list[float], target_z: float, rest: tuple[tuple[float, float, float], int] | None
    ) -> None:
        """``resting_on``: the object the open hand is around once it is as low as it goes --
        come down to ``rest_z``, the palm's stop the input asks below, or, with the input
        (at height ``target_z``) pushed to the reach's floor, there or no longer coming down (the robot may be carrying
        the hand to that object: its policy sets the height then); ``resting_centred``: centred
        on it along the slot (``CENTRED_M``)."""
        last, self._last_ee_z = self._last_ee_z, ee[2]
        rest_z = None if rest is None else rest[0][2]
        if rest_z is not None:
            if ee[2] > rest_z + 0.005:
                return  # still coming down to the palm's stop
        else:
            if target_z > self._reach_box[0][2] + 1e-6:
                return  # the input does not ask it lower than it goes
            if ee[2] > target_z + 0.005 and abs(ee[2] - last) >= 2e-4:
                return  # still coming down
        guard, fallen = self.guard, self.accidents.fallen
        k = guard.under_palm(ee, self._footprints, skip=fallen, left=guard.palm_left)
        if k is None and rest is not None:
            k = rest[1]  # a part of the hand above the palm stopped beside a tall object
        if k is not None:
            self.resting_on = k
            self.resting_offset = ee[0] - self._footprints[k][0]
            self.resting_centred = (
                abs(self.resting_offset) <= CENTRED_M
                and guard.around(ee, self._footprints, skip=fallen) == k
            )

    def _offset(self) -> float:
        """``grasp_offset`` now: the open hand's offset along x from the middle of the object
        it is down around, if more than ``CENTRED_M``, else 0."""
        ee = self._ee.tolist()
        k = self.guard.under_palm(ee, self._footprints, skip=self.accidents.fallen)
        if k is None:
            return 0.0
        ox, _, _, top, _ = self._footprints[k]
        off = ee[0] - ox
        return off if ee[2] < top and abs(off) > CENTRED_M else 0.0

    @property
    def held_above(self) -> int | None:
        """The object the open hand is held above (``app.teleop.guarded_descent``), or ``None``."""
        return self.guard.held

    def _follow_objects(self, events: list[TrialEvent]) -> None:
        """Re-aim the robot at objects a grasp moved: ``G_k <-`` object ``k``'s grasp point now,
        with its grasp configuration by IK from the old one, once ``G_k`` is ``GOAL_MOVED_M``
        off. Each move is logged (a ``goal_moved`` event with the new position) at the tick it
        takes effect, so a replay can apply it. A knocked-over object keeps its goal (no
        top-down grasp there) until it is stood up again.
        """
        goals = self.blender.goals
        off = np.linalg.norm(self._grasp_points - goals.positions, axis=1)
        moves = {}
        for k in np.flatnonzero(off > GOAL_MOVED_M).tolist():
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
            self.grasp_offset = self._offset()
        held = self.task.control(q, self.t, request=request, events=events)
        if held is not None:  # the task drives the arm: the open hand rests on nothing
            self.resting_on, self.resting_centred = None, False
            return held, held, held
        fused = self.fused
        if fused is not None and fused.ik is self.ik:
            u, rec = fused.step(q, self._steer(), x=self.user_input, robot_x=self._ee)
        else:
            u = self.ik(q, self._steer())
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


def _rows(footprints: tuple[Footprint, ...]) -> np.ndarray:
    """The objects' footprints as an ``(n, 5)`` float array (``steer_core.steer``)."""
    return np.array(footprints, dtype=np.float64).reshape(-1, 5)


def _descent_guard(scene: Scene, reach_below_m: float) -> DescentGuard:
    """The trial's ``DescentGuard`` for ``scene``'s hand (its fingertips ``reach_below_m`` under
    the TCP): its palm, the lowest layer above the fingers, and the parts above the palm (not
    the link before the last joint: its box, far off the TCP's axis, turns with it and reaches
    12-16 cm around it, where the link is not)."""
    palm = min(scene.hand[1:], key=lambda layer: layer.lo, default=None)
    upper = tuple(layer for layer in scene.hand[1:] if layer is not palm)
    above = min((layer.lo for layer in upper), default=0.0)
    return DescentGuard(
        reach_below=reach_below_m,
        slot=scene.spec.gripper_open,
        palm_above=palm.lo if palm is not None else math.inf,
        palm_half=_half_extent(palm),
        parts=tuple((layer.lo, *_half_extent(layer)) for layer in upper if not layer.turns),
        low=scene.reach.lo[2] + above,  # the arm above the palm, the hand at the reach's floor
    )


def _half_extent(layer: HandLayer | None) -> tuple[float, float]:
    """How far ``layer`` reaches to each side of the TCP along world x and y (its box about
    its centre; the TCP's x and y are the world's for the top-down hand)."""
    if layer is None:
        return (0.0, 0.0)
    return (abs(layer.center[0]) + layer.half[0], abs(layer.center[1]) + layer.half[1])


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

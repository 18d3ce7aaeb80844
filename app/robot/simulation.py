"""Physics of one trial: MuJoCo steps, position actuators tracking the command, the gripper.

``Simulation(scene)`` owns one ``MjData`` for the scene's shared, compiled model. Each control
tick ``step(command, gripper_closed=..., substeps=n)`` sets the seven joint servos to the
command (clipped to the joint limits; a non-finite command is refused) and moves the gripper
servo's setpoint toward open or closed at ``GRIPPER_SPEED``, then advances ``n`` physics steps. Queries report what a trial needs to
judge the outcome: the TCP position, which object both fingers hold, object heights and tilt,
objects off the table, and the arm's contacts with objects (``arm_contacts``).

Contacts (the scene's ``contacts``): ``"always"`` (the default) -- the wrist, hand and fingers
touch every object at all times, so an arm driven the wrong way pushes or topples what is in
its path; resting objects sleep (MuJoCo islands) until touched, which keeps the physics cheap.
``"grasp"`` -- the earlier behaviour, kept for comparison: the arm passes through objects while
reaching and they rest without contacts; they come alive when a grasp starts
(``set_grip_contacts``).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from app.robot.arm import (
    GRIPPER_MAX,
    OBJECT_ARM_BIT,
    OBJECT_CONAFFINITY,
    OBJECT_CONTYPE,
    OBJECT_GRIP_BIT,
)
from app.robot.errors import PhysicsError
from app.robot.scene import Scene

_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)
GRIPPER_SPEED = 0.15  # m/s per finger, how fast the gripper's setpoint opens or closes
OFF_TABLE_M = 0.02  # an object whose centre is this far below the table top has fallen off
CONTACT_MODES = ("always", "grasp")
ARM_PARTS = ("link6", "hand", "leftfinger", "rightfinger")
"""The arm's parts that can touch anything (``arm_contacts`` reports their index). The compiled
model fuses the hand into ``panda_link7`` (a fixed joint): that body is the "hand"."""
_PART_BODIES = ("panda_link6", "panda_link7", "panda_leftfinger", "panda_rightfinger")


@dataclass(frozen=True)
class BodyPoses:
    """Every body's pose and the gripper's point at one instant: copies, safe to hand to another
    thread (a renderer) while the simulation steps on."""

    xpos: np.ndarray
    """(nbody, 3) body positions, world frame."""
    xmat: np.ndarray
    """(nbody, 9) body rotation matrices, row-major."""
    gripper: np.ndarray
    """(3,) the TCP position."""


class Simulation:
    """One trial's physics state for ``scene`` at timestep ``physics_dt``."""

    def __init__(self, scene: Scene, *, physics_dt: float = 0.002) -> None:
        self.scene = scene
        self.contacts = scene.spec.contacts
        if self.contacts not in CONTACT_MODES:  # pragma: no cover - SceneSpec checks it
            raise PhysicsError(f"contacts: one of {CONTACT_MODES}, got {self.contacts!r}")
        # The compiled model is shared by every trial of the scene: this trial changes its own
        # copy (timestep, finger-object contacts). Copying costs well under a millisecond.
        self.model = copy.copy(scene.model)
        self.model.opt.timestep = physics_dt
        self._object_geoms = np.array(scene.object_geom_ids)
        self.data = mujoco.MjData(self.model)
        self._lower = scene.arm.lower
        self._upper = scene.arm.upper
        self._left, self._right = scene.finger_body_ids
        self._object_bodies = np.array(scene.object_body_ids)
        self._body_of_geom = self.model.geom_bodyid
        self._qadr = np.array(scene.object_qpos_addr)
        self._rest_xpos = np.zeros((len(scene.object_body_ids), 3))
        self._any_live = False
        self._open = min(scene.spec.gripper_open, GRIPPER_MAX)
        if scene.gripper_actuator_id != 7:  # pragma: no cover - fixed by Arm.spec()
            raise PhysicsError("the gripper actuator must be ctrl[7]")
        self._object_dofs = np.concatenate(
            [np.arange(6) + self.model.body_dofadr[b] for b in scene.object_body_ids]
        )
        # views into MjData's buffers (they live as long as ``data``): no per-tick slicing
        d = self.data
        self._qpos_arm = d.qpos[:7]
        self._qpos = d.qpos
        self._ctrl_arm = d.ctrl[:7]
        self._ctrl_vel = d.ctrl[8:15]
        self._ctrl = d.ctrl
        self._tcp = d.site_xpos[scene.tcp_site_id]
        bodies = self._object_bodies.tolist()
        first = bodies[0] if bodies else 0
        self._objects_xpos = (  # the objects' rows of xpos as a view when they are consecutive
            d.xpos[first : first + len(bodies)]
            if bodies == list(range(first, first + len(bodies)))
            else None
        )
        self._dt = physics_dt
        # body id -> arm part index (-1: not an arm part), object index (-1: not an object)
        nbody = self.model.nbody
        self._part_of_body = np.full(nbody, -1, dtype=np.int64)
        for k, name in enumerate(_PART_BODIES):
            self._part_of_body[self.model.body(name).id] = k
        self._object_of_body = np.full(nbody, -1, dtype=np.int64)
        self._object_of_body[self._object_bodies] = np.arange(len(self._object_bodies))
        # geom id -> the same, as lists (``arm_contacts`` looks them up one by one)
        self._part_of_geom: list[int] = self._part_of_body[self._body_of_geom].tolist()
        self._object_of_geom: list[int] = self._object_of_body[self._body_of_geom].tolist()
        self._off_z = scene.spec.table.top_z - OFF_TABLE_M
        self.reset()

    def reset(self) -> None:
        """Arm at the start configuration, gripper open, objects at rest."""
        mujoco.mj_resetData(self.model, self.data)
        if self.contacts == "always":
            self._set_live(np.ones(len(self._object_bodies), dtype=bool))
        else:
            self.set_grip_contacts(False)
        self.data.qpos[:7] = self.scene.start_q
        self.data.qpos[7:9] = self.scene.spec.gripper_open
        self.data.ctrl[:7] = self.scene.start_q
        self.data.ctrl[8:15] = 0.0
        self.data.ctrl[7] = self.data.ctrl[15] = self.scene.spec.gripper_open
        mujoco.mj_forward(self.model, self.data)
        self._rest_xpos = self.data.xpos[self._object_bodies].copy()

    def objects_at_rest(self, *, tol_m: float = 0.002, tol_rad: float = 0.05) -> bool:
        """True when every object is still where the scene put it, upright and not moving."""
        moved = np.abs(self.data.xpos[self._object_bodies] - self._rest_xpos).max()
        speed = np.abs(self.data.qvel[self._object_dofs]).max()
        return bool(moved < tol_m and speed < 0.01 and self.object_tilts().max() < tol_rad)

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def q(self) -> np.ndarray:
        """Arm configuration ``Q`` (7,), a copy."""
        return self._qpos_arm.copy()

    @property
    def ee(self) -> np.ndarray:
        """TCP position (3,), world frame, a copy."""
        return self._tcp.copy()

    def poses(self) -> BodyPoses:
        """The bodies' poses and the TCP now (copies)."""
        return BodyPoses(self.data.xpos.copy(), self.data.xmat.copy(), self.ee)

    @property
    def gripper_opening(self) -> float:
        """Finger travel in metres (0 closed, 0.04 fully open)."""
        return float(self._qpos[7])

    def step(self, command: np.ndarray, *, gripper_closed: bool, substeps: int) -> None:
        """Servo the arm to ``command`` (7,) and the gripper open/closed for ``substeps`` steps.

        The velocity servos get ``(command - q) / (substeps dt)``: reach the command in one tick.
        """
        if type(command) is not np.ndarray or command.dtype != np.float64:
            command = np.asarray(command, dtype=float)
        if command.shape != (7,) or not math.isfinite(sum(command.tolist())):
            raise PhysicsError(f"command must be 7 finite joint angles, got {command!r}")
        data = self.data
        span = substeps * self._dt
        target = self._ctrl_arm  # written in place: clip(command, lower, upper)
        np.minimum(np.maximum(command, self._lower, out=target), self._upper, out=target)
        vel = self._ctrl_vel
        np.subtract(target, self._qpos_arm, out=vel)
        vel *= 1.0 / span
        # the fingers' setpoint moves at GRIPPER_SPEED (a real hand closes gently; a setpoint
        # jump would slam the fingers into the object at about 1 m/s and fling it away)
        goal = 0.0 if gripper_closed else self._open
        ctrl = self._ctrl
        setpoint = ctrl[7]
        if setpoint != goal:
            reach = GRIPPER_SPEED * span
            setpoint = (
                max(goal, setpoint - reach) if goal < setpoint else min(goal, setpoint + reach)
            )
            ctrl[7] = ctrl[15] = setpoint
        expected = data.time + span
        model = self.model
        mujoco.mj_step(model, data, nstep=substeps)
        mujoco.mj_kinematics(model, data)  # poses of the new qpos, not the last step's
        # MuJoCo resets a diverging simulation (bad acceleration) to time 0: catch that too.
        if not math.isfinite(self._qpos_arm[0]) or data.time < expected - 1e-9:
            raise PhysicsError("physics diverged (non-finite state); the trial cannot go on")

    @property
    def grip_contacts(self) -> bool:
        """True while any object is live (touchable, under gravity)."""
        return bool(self.model.geom_contype[self._object_geoms].any())

    def set_grip_contacts(self, on: bool, *, only: Sequence[int] | None = None) -> None:
        """Objects live (contacts, gravity) or at rest (untouchable, gravity-compensated).

        With ``contacts = "grasp"`` a trial calls this: while the user reaches, the arm passes
        through the objects, so nothing can move them; once the gripper closes they fall under
        gravity again, stand on the table and the fingers take hold of whatever lies between
        them. With ``"always"`` objects are live from ``reset`` on and a trial never calls it.
        ``only`` (object indices) wakes just those objects; ``on=False`` rests every object.
        """
        n = len(self._object_bodies)
        live = np.zeros(n, dtype=bool)
        if on:
            live[list(range(n)) if only is None else list(only)] = True
        self._set_live(live)

    def _set_live(self, live: np.ndarray) -> None:
        """Live objects collide and fall; the others rest, gravity-compensated and untouchable."""
        arm_bit = OBJECT_ARM_BIT if self.contacts == "always" else 0
        contype = np.where(live, OBJECT_CONTYPE, 0)
        affinity = np.where(live, OBJECT_CONAFFINITY | OBJECT_GRIP_BIT | arm_bit, 0)
        m = self.model
        m.geom_contype[self._object_geoms] = contype
        m.geom_conaffinity[self._object_geoms] = affinity
        m.body_contype[self._object_bodies] = contype  # the broadphase filters bodies first
        m.body_conaffinity[self._object_bodies] = affinity
        m.body_gravcomp[self._object_bodies] = np.where(live, 0.0, 1.0)
        self._any_live = bool(live.any())
        for k in np.flatnonzero(~live):
            self.data.qvel[self._object_dofs[6 * k : 6 * k + 6]] = 0.0

    def arm_contacts(self) -> list[tuple[int, int, float]]:
        """The arm's touches now: ``(part, object, normal force N)`` per contact point, ``part``
        indexing ``ARM_PARTS`` and ``object`` the scene's objects (after the last substep)."""
        ncon = self.data.ncon
        if ncon == 0:
            return []
        contact = self.data.contact
        # in scalars (a grasp's ticks have 8-30 points; numpy's calls on arrays that small
        # cost more than the loop): the pairs' arm part and object by geom, from lists
        part, obj = self._part_of_geom, self._object_of_geom
        out = []
        adr: list[int] = []
        efc = self.data.efc_force
        for i, (g1, g2) in enumerate(contact.geom[:ncon].tolist()):
            p1, p2 = part[g1], part[g2]
            # a pair is arm-object when one side is an arm part and the other an object
            if (p1 >= 0 and obj[g2] >= 0) or (p2 >= 0 and obj[g1] >= 0):
                if not adr:
                    adr = contact.efc_address[:ncon].tolist()
                a = adr[i]
                force = max(float(efc[a]), 0.0) if a >= 0 else 0.0
                out.append((p1, obj[g2], force) if p1 >= 0 else (p2, obj[g1], force))
        return out

    def objects_off_table(self) -> list[int]:
        """Indices of the objects whose centre fell below the table top (pushed off)."""
        off_z = self._off_z
        z = self.data.xpos[self._object_bodies, 2].tolist()
        return [k for k, zk in enumerate(z) if zk < off_z]

    def objects_near(self, point: np.ndarray, radius: float) -> list[int]:
        """Indices of the objects whose centre lies within ``radius`` of ``point`` in the xy plane."""
        xy = self.data.xpos[self._object_bodies, :2] - np.asarray(point)[:2]
        return [int(k) for k in np.flatnonzero(np.hypot(xy[:, 0], xy[:, 1]) < radius)]

    @property
    def objects_live(self) -> bool:
        """True while any object is live; resting objects stay exactly where they are."""
        return self._any_live

    @property
    def rest_positions(self) -> np.ndarray:
        """Object centres (n, 3) as the scene placed them (at the last ``reset``)."""
        return self._rest_xpos

    def object_positions(self) -> np.ndarray:
        """Object centres (n, 3) in the order of the scene's objects (a new array)."""
        view = self._objects_xpos
        if view is not None:
            return view.copy()  # a slice copied: cheaper than indexing by an array
        return self.data.xpos[self._object_bodies]  # indexing by an array copies

    def object_heights(self) -> np.ndarray:
        """How far each object's centre is above its rest height (n,), metres."""
        return self.data.xpos[self._object_bodies, 2] - self.scene.object_rest_z

    def object_tilts(self) -> np.ndarray:
        """Angle between each object's z axis and the world's vertical (n,), radians."""
        zz = self.data.xmat[self._object_bodies, 8]
        np.maximum(zz, -1.0, out=zz)  # np.clip's numbers without its Python wrapper
        np.minimum(zz, 1.0, out=zz)
        return np.arccos(zz, out=zz)

    def held_object(self) -> int | None:
        """Index of the object both fingers touch, or ``None``."""
        ncon = self.data.ncon
        if ncon == 0:
            return None
        bodies = self._body_of_geom[self.data.contact.geom[:ncon]].tolist()
        left, right = self._left, self._right
        touch_left, touch_right = set(), set()  # the bodies each finger touches
        for b1, b2 in bodies:
            if b1 == left:
                touch_left.add(b2)
            elif b1 == right:
                touch_right.add(b2)
            if b2 == left:
                touch_left.add(b1)
            elif b2 == right:
                touch_right.add(b1)
        both = touch_left & touch_right
        if both:
            for i, body in enumerate(self._object_bodies.tolist()):
                if body in both:
                    return i
        return None

"""Physics of one trial: MuJoCo steps, position actuators tracking the command, the gripper.

``Simulation(scene)`` owns one ``MjData`` for the scene's shared, compiled model. Each control
tick ``step(command, gripper_closed=..., substeps=n)`` sets the seven joint servos to the
command (clipped to the joint limits; a non-finite command is refused) and moves the gripper
servo's setpoint toward open or closed at ``GRIPPER_SPEED``, then advances ``n`` physics steps. Queries report what a trial needs to
judge the outcome: the TCP position, which object both fingers hold, object heights and tilt.
The arm passes through objects while reaching and the objects rest (no contacts to solve); they
come alive when a grasp starts (``set_grip_contacts``), so assistance never knocks a bottle over
on its way in and the reaching phase simulates fast.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import mujoco
import numpy as np

from app.robot.arm import GRIPPER_MAX, OBJECT_CONAFFINITY, OBJECT_CONTYPE, OBJECT_GRIP_BIT
from app.robot.errors import RobotError
from app.robot.scene import Scene

_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)
GRIPPER_SPEED = 0.15  # m/s per finger, how fast the gripper's setpoint opens or closes


class SimulationError(RobotError):
    """The physics diverged or was given a command it cannot take."""


class Simulation:
    """One trial's physics state for ``scene`` at timestep ``physics_dt``."""

    def __init__(self, scene: Scene, *, physics_dt: float = 0.002) -> None:
        self.scene = scene
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
            raise SimulationError("the gripper actuator must be ctrl[7]")
        self._object_dofs = np.concatenate(
            [np.arange(6) + self.model.body_dofadr[b] for b in scene.object_body_ids]
        )
        # views into MjData's buffers (they live as long as ``data``): no per-tick slicing
        d = self.data
        self._qpos_arm = d.qpos[:7]
        self._ctrl_arm = d.ctrl[:7]
        self._ctrl_vel = d.ctrl[8:15]
        self._ctrl = d.ctrl
        self._tcp = d.site_xpos[scene.tcp_site_id]
        self._dt = physics_dt
        self.reset()

    def reset(self) -> None:
        """Arm at the start configuration, gripper open, objects at rest."""
        mujoco.mj_resetData(self.model, self.data)
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

    @property
    def gripper_opening(self) -> float:
        """Finger travel in metres (0 closed, 0.04 fully open)."""
        return float(self.data.qpos[7])

    def step(self, command: np.ndarray, *, gripper_closed: bool, substeps: int) -> None:
        """Servo the arm to ``command`` (7,) and the gripper open/closed for ``substeps`` steps.

        The velocity servos get ``(command - q) / (substeps dt)``: reach the command in one tick.
        """
        if type(command) is not np.ndarray or command.dtype != np.float64:
            command = np.asarray(command, dtype=float)
        if command.shape != (7,) or not math.isfinite(sum(command.tolist())):
            raise SimulationError(f"command must be 7 finite joint angles, got {command!r}")
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
            raise SimulationError("physics diverged (non-finite state); the trial cannot go on")

    @property
    def grip_contacts(self) -> bool:
        """True while any object is live (touchable, under gravity)."""
        return bool(self.model.geom_contype[self._object_geoms].any())

    def set_grip_contacts(self, on: bool, *, only: Sequence[int] | None = None) -> None:
        """Objects live (contacts, gravity) while grasping; at rest and untouchable while reaching.

        While the user reaches, the arm passes through the objects, so nothing can move them:
        they rest where they stand with gravity compensated and no contacts to solve (the
        physics step costs a third). Once the gripper closes they fall under gravity again,
        stand on the table and the fingers take hold of whatever lies between them. ``only``
        (object indices) wakes just those objects; ``on=False`` puts every object to rest.
        """
        n = len(self._object_bodies)
        live = np.zeros(n, dtype=bool)
        if on:
            live[list(range(n)) if only is None else list(only)] = True
        contype = np.where(live, OBJECT_CONTYPE, 0)
        affinity = np.where(live, OBJECT_CONAFFINITY | OBJECT_GRIP_BIT, 0)
        m = self.model
        m.geom_contype[self._object_geoms] = contype
        m.geom_conaffinity[self._object_geoms] = affinity
        m.body_contype[self._object_bodies] = contype  # the broadphase filters bodies first
        m.body_conaffinity[self._object_bodies] = affinity
        m.body_gravcomp[self._object_bodies] = np.where(live, 0.0, 1.0)
        self._any_live = bool(live.any())
        for k in np.flatnonzero(~live):
            self.data.qvel[self._object_dofs[6 * k : 6 * k + 6]] = 0.0

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
        """Object centres (n, 3) in the order of the scene's objects."""
        return self.data.xpos[self._object_bodies].copy()

    def object_heights(self) -> np.ndarray:
        """How far each object's centre is above its rest height (n,), metres."""
        return self.data.xpos[self._object_bodies, 2] - self.scene.object_rest_z

    def object_tilts(self) -> np.ndarray:
        """Angle between each object's z axis and the world's vertical (n,), radians."""
        zz = self.data.xmat[self._object_bodies, 8]
        return np.arccos(np.clip(zz, -1.0, 1.0))

    def held_object(self) -> int | None:
        """Index of the object both fingers touch, or ``None``."""
        ncon = self.data.ncon
        if ncon == 0:
            return None
        geoms = self.data.contact.geom[:ncon]
        b1 = self._body_of_geom[geoms[:, 0]]
        b2 = self._body_of_geom[geoms[:, 1]]
        for i, body in enumerate(self._object_bodies):
            left = np.any((b1 == body) & (b2 == self._left)) or np.any(
                (b2 == body) & (b1 == self._left)
            )
            if not left:
                continue
            right = np.any((b1 == body) & (b2 == self._right)) or np.any(
                (b2 == body) & (b1 == self._right)
            )
            if right:
                return i
        return None

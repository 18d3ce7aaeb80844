"""Physics of one trial: MuJoCo steps, position actuators tracking the command, the gripper.

``Simulation(scene)`` owns one ``MjData`` for the scene's shared, compiled model. Each control
tick ``step(command, gripper_closed=..., substeps=n)`` sets the seven joint servos to the
command (clipped to the joint limits; a non-finite command is refused) and the gripper servo
to open or closed, then advances ``n`` physics steps. Queries report what a trial needs to
judge the outcome: the TCP position, which object both fingers hold, object heights and tilt.
The arm passes through objects while reaching; the fingers touch them once a grasp starts
(``set_grip_contacts``), so assistance never knocks a bottle over on its way in.
"""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np

from app.robot.arm import GRIPPER_MAX, OBJECT_CONAFFINITY, OBJECT_GRIP_BIT
from app.robot.errors import RobotError
from app.robot.scene import Scene

_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)


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
        self.reset()

    def reset(self) -> None:
        """Arm at the start configuration, gripper open, objects at rest."""
        mujoco.mj_resetData(self.model, self.data)
        self.set_grip_contacts(False)
        self.data.qpos[:7] = self.scene.start_q
        self.data.qpos[7:9] = self.scene.spec.gripper_open
        self.data.ctrl[:7] = self.scene.start_q
        self.data.ctrl[8:15] = 0.0
        self.data.ctrl[self.scene.gripper_actuator_id] = self.scene.spec.gripper_open
        mujoco.mj_forward(self.model, self.data)

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def q(self) -> np.ndarray:
        """Arm configuration ``Q`` (7,), a copy."""
        return self.data.qpos[:7].copy()

    @property
    def ee(self) -> np.ndarray:
        """TCP position (3,), world frame, a copy."""
        return self.data.site_xpos[self.scene.tcp_site_id].copy()

    @property
    def gripper_opening(self) -> float:
        """Finger travel in metres (0 closed, 0.04 fully open)."""
        return float(self.data.qpos[7])

    def step(self, command: np.ndarray, *, gripper_closed: bool, substeps: int) -> None:
        """Servo the arm to ``command`` (7,) and the gripper open/closed for ``substeps`` steps.

        The velocity servos get ``(command - q) / (substeps dt)``: reach the command in one tick.
        """
        command = np.asarray(command, dtype=float)
        if command.shape != (7,) or not math.isfinite(command.sum()):
            raise SimulationError(f"command must be 7 finite joint angles, got {command!r}")
        target = np.minimum(np.maximum(command, self._lower), self._upper)
        self.data.ctrl[8:15] = (target - self.data.qpos[:7]) / (substeps * self.model.opt.timestep)
        self.data.ctrl[:7] = target
        self.data.ctrl[self.scene.gripper_actuator_id] = (
            0.0 if gripper_closed else min(self.scene.spec.gripper_open, GRIPPER_MAX)
        )
        mujoco.mj_step(self.model, self.data, nstep=substeps)
        mujoco.mj_kinematics(self.model, self.data)  # poses of the new qpos, not the last step's
        if (
            not np.isfinite(self.data.qpos[0])
            or self.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number
        ):
            raise SimulationError("physics diverged (non-finite state); the trial cannot go on")

    @property
    def grip_contacts(self) -> bool:
        return bool(self.model.geom_conaffinity[self._object_geoms[0]] & OBJECT_GRIP_BIT)

    def set_grip_contacts(self, on: bool) -> None:
        """Let the fingers touch the objects (while grasping) or pass through them (reaching).

        While the user reaches, the arm never pushes objects over; the fingers take hold of
        whatever lies between them once the gripper closes.
        """
        affinity = OBJECT_CONAFFINITY | OBJECT_GRIP_BIT if on else OBJECT_CONAFFINITY
        self.model.geom_conaffinity[self._object_geoms] = affinity
        self.model.body_conaffinity[self._object_bodies] = affinity  # broadphase filter

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

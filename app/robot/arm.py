"""The Panda arm as one model with two views: a MuJoCo spec (physics) and pinocchio ``Kinematics``.

``load_arm()`` is cached: the URDF is read and converted once per process. ``Arm.spec()`` returns
a fresh ``MjSpec`` of the arm with a servo on each of the seven joints, a servo per finger
(both get the same opening), gravity compensation and a ``tcp``
site placed where pinocchio's TCP frame is, so both views report the same end-effector pose.

Each joint servo is a position actuator (``ctrl[0:7]``, stiffness ``KP``) plus a velocity
actuator (``ctrl[8:15]``, damping ``KV``): torque ``= KP (q_cmd - q) + KV (qd_cmd - qd)``.
A command ``U = Q + u`` per tick is tracked at its own speed (``qd_cmd = u / dt``) instead of
lagging behind a damper that pulls toward rest. ``ctrl[7]`` and ``ctrl[15]`` are the finger
openings (the same value). Each fingertip's inner face is two capsules along the slot
(``_pad_capsules``): an object closed on off its axis along the slot is held as by a real pad.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from app.robot.assets import panda_urdf
from app.robot.errors import ModelMismatchError
from app.robot.kinematics import FINGER_JOINTS, Kinematics

ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
LAST_ARM_BODY = "panda_link7"
TCP_SITE = "tcp"
GRIPPER_ACTUATOR = "gripper"
GRIPPER_MIRROR = "gripper_mirror"
VELOCITY_SUFFIX = "_velocity"
# Position servo gains per joint (N m / rad), damping (N m s / rad) and torque limits (N m).
KP = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
KV = (450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0)
TORQUE = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
GRIPPER_KP = 400.0  # N / m on the finger opening: squeezes a 6 cm bottle with ~12 N
GRIPPER_KV = 10.0  # N s / m, about critical for the fingers (never saturates: smooth)
GRIPPER_FORCE = 40.0  # N, per finger
GRIPPER_MAX = 0.04  # m, finger travel
# Collision bits (MuJoCo collides a pair when contype_a & conaffinity_b or the reverse is set).
# Table and floor (contype 1, conaffinity 1|2) stop everything; the arm (2) never collides with
# itself (conaffinity 0). Objects (contype 1, conaffinity 1 | OBJECT_ARM_BIT) stand on the table,
# touch each other and are touched by the wrist, hand and fingers (``contacts = "always"``, the
# default). With ``contacts = "grasp"`` (the earlier behaviour) an object drops the arm bit and
# only the fingers (2|4) touch it while its conaffinity has bit 4, set while the gripper closes.
ARM_CONTYPE, ARM_CONAFFINITY = 2, 0
FINGER_CONTYPE = 2 | 4
WORLD_CONTYPE, WORLD_CONAFFINITY = 1, 3
LOW_LINKS = ("panda_link6", "panda_link7", "panda_hand", "panda_leftfinger", "panda_rightfinger")
OBJECT_CONTYPE, OBJECT_CONAFFINITY, OBJECT_GRIP_BIT = 1, 1, 4
OBJECT_ARM_BIT = 2
# Each fingertip's inner face: PAD_ROWS capsules along the slot of radius PAD_RADIUS, the tip's
# box recessed behind them by a radius, contacts with time constant PAD_TIMECONST (see
# ``_pad_capsules``).
PAD_ROWS = 2
PAD_RADIUS = 0.003  # m
PAD_TIMECONST = 0.007  # s
_PAD_ATTRIBUTES = ("friction", "contype", "conaffinity", "solimp", "condim", "priority", "rgba")


@dataclass(frozen=True, eq=False)
class Arm:
    """The Panda: joint names and limits, pinocchio kinematics, and a MuJoCo spec factory."""

    urdf: str
    kinematics: Kinematics
    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    def spec(self) -> mujoco.MjSpec:
        """A fresh MuJoCo spec of the arm alone, ready for a scene to add table and objects."""
        return _arm_spec(self.urdf, self.kinematics)

    def within_limits(self, q: np.ndarray, *, tol: float = 1e-9) -> bool:
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))


@functools.cache
def load_arm() -> Arm:
    """Load the Panda once per process (``ModelNotFoundError`` if the package is missing)."""
    urdf = panda_urdf()
    kin = Kinematics(urdf)
    if kin.joint_names != ARM_JOINTS:
        raise ModelMismatchError(
            f"unexpected Panda joints {kin.joint_names}; expected {ARM_JOINTS}"
        )
    return Arm(
        urdf=urdf,
        kinematics=kin,
        joint_names=ARM_JOINTS,
        lower=kin.lower.copy(),
        upper=kin.upper.copy(),
    )


def _arm_spec(urdf: str, kin: Kinematics) -> mujoco.MjSpec:
    spec = mujoco.MjSpec.from_string(urdf)
    spec.modelname = "panda_scene"
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    # Resting objects sleep (MuJoCo islands): an object no one touches costs no dynamics; a
    # touch from the arm wakes it. Newton with few iterations converges for these small islands.
    spec.option.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    spec.compiler.autolimits = True
    spec.compiler.discardvisual = False  # keep the upper links, which collide with nothing
    for body in spec.bodies:
        if body.name.startswith("panda_"):
            body.gravcomp = 1.0
    for geom in spec.geoms:
        # Only the wrist, hand and fingers can reach the table; the upper links never collide.
        low = geom.parent.name in LOW_LINKS
        geom.contype = ARM_CONTYPE if low else 0
        geom.conaffinity = ARM_CONAFFINITY
        geom.rgba = [0.92, 0.92, 0.95, 1.0]
    for name in (*ARM_JOINTS, *FINGER_JOINTS):
        joint = spec.joint(name)
        joint.armature = 0.1 if name in ARM_JOINTS else 0.01
        joint.damping = [1.0 if name in ARM_JOINTS else 2.0, 0.0, 0.0]
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        for geom in spec.body(finger).geoms:
            geom.friction = [1.5, 0.01, 0.001]
            geom.contype = FINGER_CONTYPE
            geom.solref = [0.004, 1.0]  # stiff pads: grip by friction, not by sinking in
            geom.solimp = [0.95, 0.99, 0.001, 0.5, 2.0]
            geom.condim = 4
            geom.priority = 1
            geom.rgba = [0.25, 0.25, 0.28, 1.0]
        _pad_capsules(spec.body(finger))
    placement = kin.tcp_in_last_joint
    site = spec.body(LAST_ARM_BODY).add_site()
    site.name = TCP_SITE
    site.pos = placement.translation.tolist()
    site.quat = _wxyz(placement.rotation).tolist()
    site.size = [0.005, 0.005, 0.005]
    site.rgba = [1.0, 0.3, 0.2, 0.0]
    for name, kp, torque in zip(ARM_JOINTS, KP, TORQUE, strict=True):
        act = spec.add_actuator()
        act.name = name
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_position(kp=kp)
        act.forcerange = [-torque, torque]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        lo, hi = spec.joint(name).range
        act.ctrlrange = [lo, hi]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    # The URDF's mimic joint becomes an equality constraint, which costs a constraint solve on
    # every step; two finger servos with the same command keep the fingers symmetric for free.
    for equality in list(spec.equalities):
        spec.delete(equality)
    _add_finger_servo(spec, GRIPPER_ACTUATOR, FINGER_JOINTS[0])
    for name, kv, torque in zip(ARM_JOINTS, KV, TORQUE, strict=True):
        act = spec.add_actuator()
        act.name = f"{name}{VELOCITY_SUFFIX}"
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.set_to_velocity(kv=kv)
        act.forcerange = [-torque, torque]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    _add_finger_servo(spec, GRIPPER_MIRROR, FINGER_JOINTS[1])
    return spec


def _pad_capsules(finger: mujoco.MjsBody) -> None:
    """The fingertip box's inner face as ``PAD_ROWS`` capsules along the slot, the box recessed.

    MuJoCo's convex collider gives a box's edge on a cylinder the box's side as normal (a mug
    closed on 1 cm or more off its axis was squeezed out along the slot); a capsule's rounded end
    gives the mug's own normal and meets a flat face at its two ends (four contacts, as the box).
    7-ms contacts: at 5 ms (the box's 4 ms, raised at the 2.5-ms step) a box lifted off the table
    lost a finger's contacts for a tick. Within the old outline: the hand's bounding boxes hold.
    """
    tip = max(finger.geoms, key=lambda g: g.pos[2])  # the URDF's fingertip box
    hx, hy, hz = tip.size
    inward = -1.0 if tip.pos[1] > 0 else 1.0  # from the tip's centre toward the other finger
    face = tip.pos[1] + inward * hy
    r = PAD_RADIUS
    tip.size = [hx, hy - r / 2, hz]
    tip.pos = [tip.pos[0], tip.pos[1] - inward * r / 2, tip.pos[2]]
    along_slot = [math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0]  # capsule z -> x
    for z in np.linspace(tip.pos[2] - hz + r, tip.pos[2] + hz - r, PAD_ROWS):
        capsule = finger.add_geom()
        capsule.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        capsule.size = [r, hx - r, 0.0]
        capsule.pos = [tip.pos[0], face - inward * r, z]
        capsule.quat = along_slot
        for attr in _PAD_ATTRIBUTES:
            setattr(capsule, attr, getattr(tip, attr))
        capsule.solref = [PAD_TIMECONST, 1.0]


def _add_finger_servo(spec: mujoco.MjSpec, name: str, joint: str) -> None:
    grip = spec.add_actuator()
    grip.name = name
    grip.target = joint
    grip.trntype = mujoco.mjtTrn.mjTRN_JOINT
    grip.set_to_position(kp=GRIPPER_KP, kv=GRIPPER_KV)
    grip.forcerange = [-GRIPPER_FORCE, GRIPPER_FORCE]
    grip.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    grip.ctrlrange = [0.0, GRIPPER_MAX]
    grip.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE


def _wxyz(rotation: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).reshape(9))
    return quat

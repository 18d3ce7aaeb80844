"""Scenes built from data: the arm, a table and graspable objects, compiled once and cached.

``build_scene(spec)`` adds the table and objects of a ``SceneSpec`` to the arm's MuJoCo spec,
computes each object's grasp frame (top-down, fingers closing across the object; a pre-grasp
standoff up the approach axis that lifts the open fingertips ``PREGRASP_CLEARANCE`` above the
object's top; the object's envelope) and its goal configuration by IK from the start
configuration, and reads the hand's collision parts from the model (``app.robot.hand``). An
object the arm cannot grasp raises ``UnreachableError`` naming it. The compiled model is shared
read-only by every trial of that scene; each trial makes its own ``MjData`` (see
``Simulation``); ``Scene.arm_model(kinematics)`` gives a grasping policy the arm it steers.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from app.blending.goals import GoalSet
from app.blending.policy_grasp import ArmModel, HandLayer
from app.robot.arm import (
    ARM_JOINTS,
    GRIPPER_ACTUATOR,
    GRIPPER_MAX,
    OBJECT_CONAFFINITY,
    OBJECT_CONTYPE,
    TCP_SITE,
    WORLD_CONAFFINITY,
    WORLD_CONTYPE,
    Arm,
    load_arm,
)
from app.robot.errors import SceneError, UnreachableError
from app.robot.hand import hand_layers
from app.robot.kinematics import Kinematics, downward_rotation
from app.robot.scene_spec import ObjectSpec, SceneSpec
from app.teleop.reach import ReachRegion

GRASP_DEPTH = 0.03  # m, TCP below the object's top when grasping
PREGRASP_CLEARANCE = 0.03  # m, open fingertips above the object's top at the pre-grasp point
# Sliding, torsional and rolling friction of objects and table. Rolling: torque = mu_r N, a
# rolling-resistance coefficient mu_r / r of about 0.03 for a 3-cm bottle (plastic on wood
# with a rim or label: 0.01-0.05), so a knocked-over bottle rolls some decimetres and stops
# instead of rolling off any table (condim 6 enables it).
OBJECT_FRICTION = (0.5, 0.005, 0.001)


@dataclass(frozen=True, eq=False)
class Scene:
    """A compiled scene: MuJoCo model, goals (grasp poses and goal configurations), reach, start.

    ``goals.positions`` are the TCP grasp points, ``goals.configurations`` the IK solutions,
    ``goals.standoffs`` and ``goals.envelopes`` the pre-grasp distances and the objects'
    envelopes, all in the order of ``spec.objects``; ``object_rest_z`` the objects' initial
    heights; ``hand`` the hand's collision parts with the scene's finger opening.
    """

    spec: SceneSpec
    arm: Arm
    model: mujoco.MjModel
    goals: GoalSet
    grasp_rotations: np.ndarray
    reach: ReachRegion
    start_q: np.ndarray
    start_ee: np.ndarray
    object_body_ids: tuple[int, ...]
    object_qpos_addr: tuple[int, ...]
    object_rest_z: np.ndarray
    object_geom_ids: tuple[int, ...]
    tcp_site_id: int
    gripper_actuator_id: int
    finger_body_ids: tuple[int, int]
    hand: tuple[HandLayer, ...]

    def arm_model(self, kinematics: Kinematics) -> ArmModel:
        """The arm as a grasping policy sees it, steered through ``kinematics`` (give each
        trial its own copy: pinocchio's data is not shared between threads)."""
        return ArmModel(
            pose_jacobian=kinematics.pose_and_jacobian,
            layers=self.hand,
            slot=self.spec.gripper_open,
            table_z=self.spec.table.top_z,
            lower=self.arm.lower,
            upper=self.arm.upper,
        )

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def target(self) -> str:
        return self.spec.target

    @functools.cached_property
    def target_index(self) -> int:
        return self.spec.target_index

    @functools.cached_property
    def object_names(self) -> tuple[str, ...]:
        return self.spec.object_names


def grasp_rotation(obj: ObjectSpec) -> np.ndarray:
    """TCP rotation for a top-down grasp: z down, x (approach) along world x, as at the start.

    The fingers close along world y, across the object when the hand comes outward from the
    robot (the way a reach-limited user pushes toward a far object). A box is gripped across
    the pair of faces nearest that direction: ``psi = yaw + k pi/2`` closest to 0.
    """
    return downward_rotation(_grasp_yaw(obj))


def _grasp_yaw(obj: ObjectSpec) -> float:
    if obj.shape == "box":
        return obj.yaw - round(obj.yaw / (math.pi / 2)) * (math.pi / 2)
    return 0.0


def grasp_position(obj: ObjectSpec) -> np.ndarray:
    top = obj.position[2] + obj.half_height
    return np.array([obj.position[0], obj.position[1], top - grasp_depth(obj)])


def grasp_depth(obj: ObjectSpec) -> float:
    """How far below the object's top the TCP grasps it (m)."""
    return min(GRASP_DEPTH, obj.half_height)


def envelope(obj: ObjectSpec) -> tuple[float, float, float]:
    """The object as its grasp sees it (``GoalSet.envelopes``): footprint radius, its top above
    the grasp point, and its half-width across the fingers' closing direction (the TCP's y
    axis; for a box, the half-extent along whichever of its axes that is)."""
    half_width = obj.size[0]
    if obj.shape == "box":
        turns = round((obj.yaw - _grasp_yaw(obj)) / (math.pi / 2))
        half_width = obj.size[1] if turns % 2 == 0 else obj.size[0]
    return obj.footprint_radius, grasp_depth(obj), half_width


def build_scene(spec: SceneSpec, arm: Arm | None = None) -> Scene:
    """Compile (or fetch from the cache) the scene described by ``spec``."""
    return _build_scene(spec, arm or load_arm())


@functools.lru_cache(maxsize=32)
def _build_scene(spec: SceneSpec, arm: Arm) -> Scene:
    start_q = np.array(spec.start_q, dtype=float)
    if not arm.within_limits(start_q):
        bad = [
            f"{name}={v:.3f} not in [{lo:.3f}, {hi:.3f}]"
            for name, v, lo, hi in zip(arm.joint_names, start_q, arm.lower, arm.upper, strict=True)
            if not lo <= v <= hi
        ]
        raise SceneError(f"scenes.{spec.name}.start_q: outside the joint limits: {'; '.join(bad)}")
    kin = arm.kinematics.copy()
    start_ee = kin.fk(start_q)
    positions, rotations, configurations = [], [], []
    for obj in spec.objects:
        pos, rot = grasp_position(obj), grasp_rotation(obj)
        result = kin.ik(pos, rotation=rot, q0=start_q, posture=start_q, tol=5e-4, rot_tol=5e-3)
        if not result.converged:
            raise UnreachableError(
                f"scenes.{spec.name}: object {obj.name!r} at {list(obj.position)} cannot be"
                f" grasped: IK misses the grasp point by {result.position_error * 100:.1f} cm;"
                " move it within about 0.75 m of the robot base",
                object_name=obj.name,
            )
        positions.append(pos)
        rotations.append(rot)
        configurations.append(result.q)
    quats = np.array([_wxyz(r) for r in rotations])
    model = _compile(spec, arm)
    tcp_site_id = model.site(TCP_SITE).id
    hand = hand_layers(model, tcp_site_id, opening=min(spec.gripper_open, GRIPPER_MAX))
    fingertips = max(0.0, -min(layer.lo for layer in hand))  # below the TCP
    envelopes = np.array([envelope(o) for o in spec.objects])
    goals = GoalSet(
        spec.object_names,
        np.array(positions),
        quats,
        np.array(configurations),
        standoffs=envelopes[:, 1] + fingertips + PREGRASP_CLEARANCE,
        envelopes=envelopes,
    )
    return Scene(
        spec=spec,
        arm=arm,
        model=model,
        goals=goals,
        grasp_rotations=np.array(rotations),
        reach=ReachRegion(np.array(spec.reach_lo), np.array(spec.reach_hi)),
        start_q=start_q,
        start_ee=start_ee,
        object_body_ids=tuple(model.body(o.name).id for o in spec.objects),
        object_qpos_addr=tuple(
            int(model.jnt_qposadr[model.body(o.name).jntadr[0]]) for o in spec.objects
        ),
        object_rest_z=np.array([o.position[2] for o in spec.objects]),
        object_geom_ids=tuple(model.geom(o.name).id for o in spec.objects),
        tcp_site_id=tcp_site_id,
        gripper_actuator_id=model.actuator(GRIPPER_ACTUATOR).id,
        finger_body_ids=(model.body("panda_leftfinger").id, model.body("panda_rightfinger").id),
        hand=hand,
    )


def _compile(spec: SceneSpec, arm: Arm) -> mujoco.MjModel:
    ms = arm.spec()
    world = ms.worldbody
    ms.visual.headlight.ambient = [0.4, 0.4, 0.4]
    light = world.add_light()
    light.pos = [0.5, -0.5, 2.0]
    light.dir = [-0.2, 0.3, -1.0]
    floor = world.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [2.0, 2.0, 0.05]
    floor.pos = [0.0, 0.0, spec.table.top_z - 0.75]
    floor.rgba = [0.55, 0.55, 0.58, 1.0]
    floor.contype, floor.conaffinity = WORLD_CONTYPE, OBJECT_CONAFFINITY  # objects only
    t = spec.table
    table = world.add_geom()
    table.name = "table"
    table.type = mujoco.mjtGeom.mjGEOM_BOX
    table.size = [t.half_size[0], t.half_size[1], t.thickness / 2]
    table.pos = [t.center[0], t.center[1], t.top_z - t.thickness / 2]
    table.rgba = [0.62, 0.48, 0.34, 1.0]
    table.friction = list(OBJECT_FRICTION)
    table.contype, table.conaffinity = WORLD_CONTYPE, WORLD_CONAFFINITY
    pedestal = world.add_geom()
    pedestal.name = "pedestal"
    pedestal.type = mujoco.mjtGeom.mjGEOM_CYLINDER
    pedestal.size = [0.12, (0.75 + t.top_z) / 2, 0.0]
    pedestal.pos = [0.0, 0.0, (t.top_z - 0.75) / 2 - 0.001]
    pedestal.rgba = [0.3, 0.3, 0.32, 1.0]
    pedestal.contype, pedestal.conaffinity = 0, 0
    for obj in spec.objects:
        body = world.add_body()
        body.name = obj.name
        body.pos = list(obj.position)
        body.quat = [math.cos(obj.yaw / 2), 0.0, 0.0, math.sin(obj.yaw / 2)]
        free = body.add_freejoint()
        free.name = f"{obj.name}_free"
        geom = body.add_geom()
        geom.name = obj.name
        if obj.shape == "cylinder":
            geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
            geom.size = [obj.size[0], obj.size[1], 0.0]
        else:
            geom.type = mujoco.mjtGeom.mjGEOM_BOX
            geom.size = list(obj.size)
        geom.mass = obj.mass
        geom.rgba = list(obj.rgba)
        geom.friction = list(OBJECT_FRICTION)
        geom.condim = 6
        geom.contype, geom.conaffinity = OBJECT_CONTYPE, OBJECT_CONAFFINITY
    try:
        model = ms.compile()
    except ValueError as exc:  # pragma: no cover - MuJoCo compiler messages are specific
        raise SceneError(f"scenes.{spec.name}: MuJoCo could not compile the scene: {exc}") from exc
    if model.nu != 2 * len(ARM_JOINTS) + 2:
        raise SceneError(f"scenes.{spec.name}: expected {2 * len(ARM_JOINTS) + 2} actuators")
    return model


def _wxyz(rotation: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).reshape(9))
    return quat

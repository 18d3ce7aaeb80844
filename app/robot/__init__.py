"""The simulated arm: one Panda model for MuJoCo (physics) and pinocchio (kinematics); scenes.

``load_arm()`` -> ``Arm`` (MuJoCo spec factory + pinocchio ``Kinematics``);
``SceneSpec.from_dict(d, where=...)`` -> ``build_scene(spec)`` -> ``Scene`` (compiled once,
cached); ``Simulation(scene, physics_dt=...)`` steps one trial's physics.
"""

import os

# Offscreen rendering (videos) is headless on these machines; MuJoCo reads this on import.
os.environ.setdefault("MUJOCO_GL", "egl")

from app.robot.arm import Arm, load_arm
from app.robot.errors import (
    ModelNotFoundError,
    RobotError,
    SceneError,
    UnreachableError,
)
from app.robot.kinematics import IKResult, Kinematics, downward_rotation
from app.robot.scene import Scene, build_scene, grasp_position, grasp_rotation
from app.robot.scene_spec import CONDITION_WORDS, ObjectSpec, SceneSpec, TableSpec
from app.robot.simulation import BodyPoses, Simulation, SimulationError

__all__ = [
    "CONDITION_WORDS",
    "Arm",
    "BodyPoses",
    "IKResult",
    "Kinematics",
    "ModelNotFoundError",
    "ObjectSpec",
    "RobotError",
    "Scene",
    "SceneError",
    "SceneSpec",
    "Simulation",
    "SimulationError",
    "TableSpec",
    "UnreachableError",
    "build_scene",
    "downward_rotation",
    "grasp_position",
    "grasp_rotation",
    "load_arm",
]

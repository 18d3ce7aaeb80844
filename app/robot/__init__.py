"""The simulated arm: one Panda model for MuJoCo (physics) and pinocchio (kinematics); scenes.

``load_arm()`` -> ``Arm`` (MuJoCo spec factory + pinocchio ``Kinematics``);
``SceneSpec.from_dict(d, where=...)`` -> ``build_scene(spec)`` -> ``Scene`` (compiled once,
cached; its goals are grasp frames, ``Scene.arm_model(kinematics)`` is the arm a grasping
policy steers, with the hand's collision layers from ``app.robot.hand``);
``Simulation(scene, physics_dt=...)`` steps one trial's physics.
"""

import os

# Offscreen rendering (videos) is headless on these machines; MuJoCo reads this on import.
os.environ.setdefault("MUJOCO_GL", "egl")

from app.robot.arm import Arm, load_arm
from app.robot.errors import (
    ModelNotFoundError,
    PhysicsError,
    RobotError,
    SceneError,
    UnreachableError,
)
from app.robot.scene import Scene, build_scene
from app.robot.scene_spec import SceneSpec
from app.robot.simulation import BodyPoses, Simulation

__all__ = [
    "Arm",
    "BodyPoses",
    "ModelNotFoundError",
    "PhysicsError",
    "RobotError",
    "Scene",
    "SceneError",
    "SceneSpec",
    "Simulation",
    "UnreachableError",
    "build_scene",
    "load_arm",
]

"""The simulated arm: one Panda model for MuJoCo (physics) and pinocchio (kinematics); scenes."""

import os

# Offscreen rendering (videos) is headless on these machines; MuJoCo reads this on import.
os.environ.setdefault("MUJOCO_GL", "egl")

from app.robot.errors import ModelNotFoundError, RobotError, SceneError, UnreachableError
from app.robot.scene_spec import ObjectSpec, SceneSpec, TableSpec

__all__ = [
    "ModelNotFoundError",
    "ObjectSpec",
    "RobotError",
    "SceneError",
    "SceneSpec",
    "TableSpec",
    "UnreachableError",
]

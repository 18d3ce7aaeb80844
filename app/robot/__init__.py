"""The simulated arm: one Panda model for MuJoCo (physics) and pinocchio (kinematics); scenes."""

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

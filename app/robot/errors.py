"""Typed errors of the robot layer: a missing model, a bad scene, an unreachable object."""

from __future__ import annotations

from app.errors import AppError


class RobotError(AppError):
    """Base class of every error raised by ``app.robot``."""


class ModelNotFoundError(RobotError, FileNotFoundError):
    """The Panda model files are not installed where ``example-robot-data`` puts them."""


class ModelMismatchError(RobotError, RuntimeError):
    """The installed robot model is not the one the platform was built for (other joints)."""


class SceneError(RobotError, ValueError):
    """A scene description is invalid; the message names the key path (``scenes.easy.objects``)."""


class UnreachableError(SceneError):
    """Inverse kinematics found no configuration for an object's grasp pose."""

    def __init__(self, message: str, *, object_name: str) -> None:
        super().__init__(message)
        self.object_name = object_name


class PhysicsError(RobotError):
    """The physics diverged or was given a command it cannot take."""

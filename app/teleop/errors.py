"""Typed errors of the teleoperation layer."""

from __future__ import annotations

from app.errors import AppError


class TeleopError(AppError, ValueError):
    """Base class of every error raised by ``app.teleop``."""


class InvalidTargetError(TeleopError):
    """A user target that is not a finite 3-vector (NaN, infinity, wrong shape)."""

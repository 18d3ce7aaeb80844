"""Typed errors of the trial layer."""

from __future__ import annotations

from app.errors import AppError


class TrialError(AppError):
    """Base class of every error raised by ``app.trial``."""


class TrialConfigError(TrialError, ValueError):
    """A trial configuration value is invalid; the message names the field and the fix."""

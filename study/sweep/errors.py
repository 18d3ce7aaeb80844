"""Typed errors of the arbitration sweep; every message says what to change."""

from __future__ import annotations

from study.errors import StudyError


class SweepError(StudyError):
    """Base class of every error raised by ``study.sweep``."""


class SweepProtocolError(SweepError, ValueError):
    """The protocol cannot be swept: a mode is missing or its arbitration is not written as an
    inline table the sweep can replace."""


class SweepGridError(SweepError, ValueError):
    """A grid value is out of range or the grid is empty."""

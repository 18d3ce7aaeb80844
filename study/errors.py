"""The root of every error ``study`` raises: ``except StudyError`` catches them all.

Each package's errors derive from it through the package's own base (``study.simulated``'s
``SimulationError``, ...), keeping the built-in mixin callers rely on (``ValueError`` for a bad
file or value, ``RuntimeError`` for a run that cannot go on).
"""

from __future__ import annotations

__all__ = ["StudyError"]


class StudyError(Exception):
    """Base class of every error raised by ``study``; the message says what was wrong and what
    to do about it."""

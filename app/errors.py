"""The root of every error ``app`` raises: ``except AppError`` catches them all.

Each package's errors derive from it through the package's own base (``RobotError``,
``TeleopError``, ``BlendingError``, ``TrialError``, ...), keeping the built-in mixin callers rely on
(``ValueError`` for a bad value or configuration, ``RuntimeError`` for a state that cannot go on,
``FileNotFoundError`` for a missing model), so ``except ValueError`` still catches what it did.
"""

from __future__ import annotations

__all__ = ["AppError"]


class AppError(Exception):
    """Base class of every error raised by ``app``; the message says what was wrong and what to
    do about it."""

"""Typed errors of the blending formalism.

Every error is an ``app.errors.AppError`` and a ``ValueError`` (so generic callers can catch it) and names the argument or
configuration key that was wrong, what was wrong with it, and what to do about it.
"""

from __future__ import annotations

from app.errors import AppError

__all__ = ["BlendingError", "ConfigError", "InvalidArbitrationError", "InvalidInputError"]


class BlendingError(AppError, ValueError):
    """Base class of every error raised by :mod:`app.blending`."""


class InvalidInputError(BlendingError):
    """An argument is unusable: NaN or infinite values, wrong shape, empty goal set, bad range."""


class InvalidArbitrationError(BlendingError):
    """An arbitration function leaves [0, 1] or decreases with confidence."""


class ConfigError(BlendingError):
    """A plain-dict configuration (protocol table) is invalid; the message names the key path.

    ``key``: the full key path (``modes.timid.arbitration.alpha_max``); ``category``:
    ``missing``, ``unknown``, ``type`` or ``value``; ``problem``: the message after the key.
    """

    def __init__(
        self, message: str, *, key: str = "", category: str = "value", problem: str = ""
    ) -> None:
        super().__init__(message)
        if not key:  # "<key>: <problem>", the form every message here takes
            head, sep, tail = message.partition(": ")
            if sep and " " not in head:
                key, problem = head, problem or tail
        self.key = key
        self.category = category
        self.problem = problem or message

"""Typed errors of the session engine. Each leaves the session and the store untouched."""

from __future__ import annotations

from numbers import Integral

from study.errors import StudyError
from study.protocol import AnswerError


class SessionError(StudyError, RuntimeError):
    """Base class of session errors."""


class SessionStateError(SessionError):
    """The action is not valid in the session's current state (the message says which are)."""


class SessionClosedError(SessionStateError):
    """The session object was closed (or lost its lease); reopen the session to continue."""


class InvalidAnswerError(SessionError, AnswerError):
    """An answer is not a whole number on its item's scale."""


class UnknownItemError(InvalidAnswerError):
    """An answer names an item that is not pending on the current screen."""


class MissingReasonError(SessionError, ValueError):
    """Skip, redo, withdraw and end need a non-empty reason for the record."""


class InvalidSeedError(SessionError, ValueError):
    """A session seed is not a whole number in 0 .. 2**63 - 1 (what the store and numpy accept)."""


MAX_SEED = 2**63 - 1
"""The largest session seed: the store keeps it as a signed 64-bit SQLite integer."""


def check_seed(seed: object, *, what: str = "the session seed") -> int:
    """``seed`` if it is a whole number in ``0..MAX_SEED``, else ``InvalidSeedError``."""
    if isinstance(seed, bool) or not isinstance(seed, Integral) or not 0 <= seed <= MAX_SEED:
        raise InvalidSeedError(
            f"{what} must be a whole number from 0 to {MAX_SEED}, got {seed!r}; pass e.g. --seed 1"
        )
    return int(seed)

"""Typed errors of the session engine. Each leaves the session and the store untouched."""

from __future__ import annotations

from study.protocol import AnswerError


class SessionError(RuntimeError):
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

"""Typed errors raised by the study store; each message names what was wrong and what to do."""

from __future__ import annotations


class StoreError(RuntimeError):
    """Base class: the store could not do what was asked; the stored data is untouched."""


class NotAStoreError(StoreError):
    """The file is not a SQLite database written by this platform."""


class SchemaVersionError(StoreError):
    """The database was written with another schema version than this code reads."""


class ProtocolMismatchError(StoreError):
    """The database was written by a different protocol (study id or content hash differ)."""


class ReadOnlyStoreError(StoreError):
    """A write was attempted on a store opened read-only."""


class InvalidParticipantIdError(StoreError, ValueError):
    """A participant ID is not a short pseudonym (letters, digits, '-', '_')."""


class UnknownParticipantError(StoreError, KeyError):
    """No participant with this ID is enrolled in the store."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class DuplicateParticipantError(StoreError):
    """A participant with this ID is already enrolled."""


class SessionLockedError(StoreError):
    """Another live process (or another session object) holds this participant's session."""


class SampleFormatError(StoreError, ValueError):
    """A tick record cannot be stored as a sample row (wrong dimensions, non-numeric values)."""

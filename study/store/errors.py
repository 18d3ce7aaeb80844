"""Typed errors raised by the study store; each message names what was wrong and what to do."""

from __future__ import annotations

from study.errors import StudyError


class StoreError(StudyError, RuntimeError):
    """Base class: the store could not do what was asked; the stored data is untouched."""


class NotAStoreError(StoreError):
    """The file is not a SQLite database written by this platform."""


class StoreDamagedError(StoreError):
    """The file is a store, but SQLite's own check finds it damaged (a disk error, a copy cut
    short, bytes overwritten). Nothing is written to it; ``python -m study salvage`` copies what
    is readable into a new store."""


class SchemaVersionError(StoreError):
    """The database was written with another schema version than this code reads."""


class ProtocolMismatchError(StoreError):
    """The database was written by a different protocol (study id or content hash differ)."""


class ReadOnlyStoreError(StoreError):
    """A write was attempted on a store opened read-only."""


class StoreWriteError(StoreError):
    """The file system refused a write (disk full, read-only file or folder, I/O error).

    Nothing of the refused write was kept; what was committed before is intact. The cause is
    outside the program, so the message names the store and what to do; a session can be
    continued (``--resume``, or re-opening it in the server) once it is fixed.

    Attributes:
        path: the store file.
    """

    def __init__(self, message: str, *, path: object = None) -> None:
        super().__init__(message)
        self.path = path


class StoreFullError(StoreWriteError):
    """The disk (or the file's size limit) is full: SQLite's "database or disk is full"."""


class StoreNotWritableError(StoreWriteError):
    """The store file or its folder cannot be written (read-only file, folder or file system).

    SQLite keeps a store's journal (``-wal``, ``-shm``) beside the file, so the folder must be
    writable too, not only the file."""


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

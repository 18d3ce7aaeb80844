"""Telling a file-system fault from a damaged or foreign file, and saying what to do about it.

SQLite reports a full disk, a read-only file or folder and a file that is not a database with
different result codes (``sqlite3.Error.sqlite_errorcode``), but with messages that are easy to
misread ("unable to open database file" for a folder it may not write into). These helpers turn
them into the store's typed errors, and probe a folder and a file for writability before a store
is opened read-write, with the process's own (effective) permissions and mount flags.
"""

from __future__ import annotations

import errno
import os
import sqlite3
import tempfile
from pathlib import Path

from study.store.errors import StoreError, StoreFullError, StoreNotWritableError, StoreWriteError

# SQLite primary result codes (the low byte of an extended code)
SQLITE_PERM = 3
SQLITE_READONLY = 8
SQLITE_IOERR = 10
SQLITE_CORRUPT = 11
SQLITE_FULL = 13
SQLITE_CANTOPEN = 14
SQLITE_NOTADB = 26


def primary_code(exc: BaseException) -> int | None:
    """SQLite's primary result code of ``exc`` (``None`` if it carries none)."""
    code = getattr(exc, "sqlite_errorcode", None)
    return None if code is None else int(code) & 0xFF


def full_message(path: Path, detail: object) -> str:
    return (
        f"store {path}: the disk is full ({detail}); nothing of this write was kept and "
        "everything committed before is intact. Free space on the disk holding "
        f"{path.resolve().parent} "
        "(df -h shows it), then continue the session (--resume, or re-open it)"
    )


def write_error(path: Path, exc: sqlite3.Error) -> StoreError:
    """The typed error for a failed write to the store at ``path``."""
    code = primary_code(exc)
    if code == SQLITE_FULL:
        return StoreFullError(full_message(path, exc), path=path)
    if code in (SQLITE_READONLY, SQLITE_PERM, SQLITE_CANTOPEN):
        return StoreNotWritableError(not_writable_message(path, exc), path=path)
    if code == SQLITE_IOERR:
        return StoreWriteError(
            f"store {path}: the disk refused a write ({exc}); nothing of this write was kept. "
            "Check the disk (space, errors in the system log), then continue the session "
            "(--resume, or re-open it)",
            path=path,
        )
    return StoreError(f"store {path}: {exc} (nothing of this write was kept)")


def not_writable_message(path: Path, detail: object) -> str:
    """Why the store at ``path`` cannot be written: probes the folder, then the file."""
    folder = path.parent
    problem = folder_problem(folder)
    if problem is not None:
        return (
            f"the folder {folder} is not writable ({_reason(problem)}); a store needs a writable "
            "folder for its journal files beside it. Move the store to a writable folder (or "
            "make this one writable); to only read it, export it (python -m study export)"
        )
    problem = file_problem(path)
    if problem is not None:
        return (
            f"the store file {path} is read-only ({_reason(problem)}); make it writable (chmod "
            "u+w) or copy it to a writable folder; to only read it, export it (python -m study "
            "export)"
        )
    return f"store {path} cannot be written ({detail}); check the file's and folder's permissions"


def folder_problem(folder: Path) -> OSError | None:
    """``None`` if this process can create (and remove) a file in ``folder``, else the error.

    A real probe rather than ``os.access``: it honours read-only mounts, the effective user and
    ACLs alike, and leaves nothing behind."""
    try:
        with tempfile.TemporaryFile(dir=folder, prefix=".store-probe-"):
            pass
    except OSError as exc:
        return exc
    return None


def file_problem(path: Path) -> OSError | None:
    """``None`` if ``path`` does not exist or this process may open it for writing (nothing is
    written), else the error."""
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return None
    except OSError as exc:
        return exc
    os.close(fd)
    return None


def check_writable(path: Path) -> None:
    """Raise ``StoreNotWritableError`` (``StoreFullError`` for a full disk) unless a store at
    ``path`` could be opened read-write: its folder must take new files (the journal) and the
    file, if it exists, must open for writing."""
    problem = folder_problem(path.parent) or file_problem(path)
    if problem is None:
        return
    if problem.errno == errno.ENOSPC:
        raise StoreFullError(full_message(path, _reason(problem)), path=path)
    raise StoreNotWritableError(not_writable_message(path, _reason(problem)), path=path)


def _reason(exc: OSError) -> str:
    if exc.errno == errno.EROFS:
        return "read-only file system"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if exc.errno == errno.ENOSPC:
        return "no space left on the device"
    return exc.strerror or str(exc)

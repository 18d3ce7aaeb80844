"""Input files read with bounds: a regular file, of at most a stated size, or a clear error.

A path a user types may name anything: a folder, ``/dev/zero`` (endless), a FIFO (``open``
waits for a writer forever), a 50 MB file where a 20 KB one belongs. :func:`check_input_file`
looks before anything is read -- without blocking, even on a FIFO -- and
:func:`read_text_file` then reads at most the limit (a file that grows meanwhile cannot make
it read more). Both raise :class:`InputFileError`, whose message names the file and the
problem.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from app.errors import AppError

MiB = 2**20


class InputFileError(AppError, ValueError):
    """An input file is missing, not a regular file, too large, or unreadable.

    ``problem`` says what, after the file's name ("does not exist", "is a folder, not a
    file", ...); the message is ``"<what> <path> <problem>"``."""

    def __init__(self, what: str, path: Path, problem: str) -> None:
        super().__init__(f"{what} {path} {problem}")
        self.path = path
        self.problem = problem


def _describe(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a pipe (FIFO)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _size(n: int) -> str:
    return f"{n / MiB:.1f} MB" if n >= MiB else f"{n / 1024:.0f} KB" if n >= 1024 else f"{n} B"


def check_input_file(path: str | Path, *, max_bytes: int, what: str = "file") -> Path:
    """``path`` when it names a readable regular file of at most ``max_bytes``, else
    :class:`InputFileError` (nothing is read)."""
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputFileError(what, p, "does not exist") from None
    except OSError as exc:
        raise InputFileError(what, p, f"cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(what, p, f"is {_describe(st.st_mode)}, not a file")
    if st.st_size > max_bytes:
        raise InputFileError(what, p, _too_large(st.st_size, max_bytes))
    if not os.access(p, os.R_OK):
        raise InputFileError(what, p, "cannot be read (permission denied)")
    return p


def _too_large(size: int | None, max_bytes: int) -> str:
    """The problem of a file of ``size`` bytes (``None``: more than read) over ``max_bytes``."""
    found = "more" if size is None else f"{_size(size)}, more"
    return f"is {found} than the {_size(max_bytes)} such a file can be; check the path"


def read_bytes_file(path: str | Path, *, max_bytes: int, what: str = "file") -> bytes:
    """The bytes of the regular file ``path`` (at most ``max_bytes``), else
    :class:`InputFileError`. Opened without blocking, checked on the open descriptor."""
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise InputFileError(what, p, "does not exist") from None
    except IsADirectoryError:
        raise InputFileError(what, p, "is a folder, not a file") from None
    except OSError as exc:
        raise InputFileError(what, p, f"cannot be read ({exc.strerror or exc})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputFileError(what, p, f"is {_describe(st.st_mode)}, not a file")
        if st.st_size > max_bytes:
            raise InputFileError(what, p, _too_large(st.st_size, max_bytes))
    except BaseException:
        os.close(fd)
        raise
    with os.fdopen(fd, "rb") as f:
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise InputFileError(what, p, _too_large(None, max_bytes))
    return data


def read_text_file(path: str | Path, *, max_bytes: int, what: str = "file") -> str:
    """The UTF-8 text of the regular file ``path`` (at most ``max_bytes``), else
    :class:`InputFileError` (also for text that is not UTF-8, with the byte offset)."""
    data = read_bytes_file(path, max_bytes=max_bytes, what=what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(
            what, Path(path), f"is not UTF-8 text (byte offset {exc.start}); re-save it as UTF-8"
        ) from None

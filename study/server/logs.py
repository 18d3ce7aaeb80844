"""The server's log: bounded in rate and in size, whatever clients do.

A client chooses how often it makes the server log (a bad handshake, a refused message, a
closed socket), so no line may be written in proportion to what clients send:

* :class:`BoundedLines` (a filter on every handler) lets at most ``per_minute`` records of one
  kind -- one logger, one message template -- through a minute, and says how many it held back
  on the next one it lets through; lines are cut to ``max_chars``. Records of the libraries a
  client drives directly (websockets, asyncio) and of the port's firewall never carry a
  traceback; other records carry theirs at most once an hour per kind (a bug that a client can
  trigger over and over is then in the log once, not once per message).
* :func:`configure` writes to stderr and to a rotating file (``max_bytes`` per file,
  ``backups`` old files kept): the log's disk use is capped at ``(backups + 1) * max_bytes``,
  and :func:`disk_use` reports it (the console shows it).
"""

from __future__ import annotations

import logging
import logging.handlers
import threading
import time
from pathlib import Path

CLIENT_DRIVEN = ("websockets", "asyncio", "study.server.firewall")
"""Loggers whose records a client causes directly: never a traceback."""

MAX_BYTES = 10 * 2**20
BACKUPS = 4
FORMAT = "%(asctime)s %(name)s: %(message)s"


class BoundedLines(logging.Filter):
    """At most ``per_minute`` records of one kind a minute, tracebacks rationed (see module)."""

    def __init__(
        self, *, per_minute: int = 10, max_chars: int = 1000, traceback_every_s: float = 3600.0
    ) -> None:
        super().__init__()
        self.per_minute = per_minute
        self.max_chars = max_chars
        self.traceback_every_s = traceback_every_s
        self._windows: dict[tuple[str, str], list[float]] = {}
        self._held: dict[tuple[str, str], int] = {}
        self._tracebacks: dict[tuple[str, str], float] = {}
        self._lock = threading.Lock()
        self.held_back = 0

    def filter(self, record: logging.LogRecord) -> bool:
        decided = getattr(record, "bounded", None)  # the same record at the next handler
        if decided is not None:
            return bool(decided)
        record.bounded = self._decide(record)
        return record.bounded

    def _decide(self, record: logging.LogRecord) -> bool:
        kind = (record.name, str(record.msg)[:200])
        now = time.monotonic()
        with self._lock:
            window = self._windows.setdefault(kind, [now, 0])
            if now - window[0] >= 60.0:
                window[0], window[1] = now, 0
            if window[1] >= self.per_minute:
                self._held[kind] = self._held.get(kind, 0) + 1
                self.held_back += 1
                return False
            window[1] += 1
            held = self._held.pop(kind, 0)
            traceback = record.exc_info is not None or record.stack_info is not None
            if traceback and (
                record.name.startswith(CLIENT_DRIVEN)
                or now - self._tracebacks.get(kind, -1e18) < self.traceback_every_s
            ):
                record.exc_info, record.exc_text, record.stack_info = None, None, None
            elif traceback:
                self._tracebacks[kind] = now
            if len(self._windows) > 4096:  # templates are the code's, but be safe
                self._windows.clear()
        message = record.getMessage()
        if held:
            message += f" [{held} more like this in the last minute]"
        if len(message) > self.max_chars:
            message = message[: self.max_chars] + "..."
        record.msg, record.args = message, None
        return True


def configure(path: Path | None, *, max_bytes: int = MAX_BYTES, backups: int = BACKUPS) -> None:
    """Log INFO and above to stderr and, with ``path``, to a rotating file there, every line
    through one :class:`BoundedLines`."""
    bounded = BoundedLines()
    handlers: list[logging.Handler] = [logging.StreamHandler()]
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        handlers.append(
            logging.handlers.RotatingFileHandler(
                path, maxBytes=max_bytes, backupCount=backups, encoding="utf-8"
            )
        )
    for handler in handlers:
        handler.setFormatter(logging.Formatter(FORMAT))
        handler.addFilter(bounded)
    logging.basicConfig(level=logging.INFO, handlers=handlers, force=True)


def disk_use(path: Path | None, *, backups: int = BACKUPS) -> int:
    """Bytes the log file and its rotated copies take (0 without a file)."""
    if path is None:
        return 0
    files = [path, *(path.with_name(f"{path.name}.{k}") for k in range(1, backups + 1))]
    return sum(f.stat().st_size for f in files if f.is_file())

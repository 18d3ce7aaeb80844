"""Log lines a client can cause, at most one per kind every so often, never a payload.

A hostile client chooses how often it breaks a rule; the log must not grow with it.
:class:`Notes` lets one line per key through every ``every_s`` seconds (escaped, cut to 300
characters); :class:`OpenLinesOnceAMinute` does the same for websockets' "connection open"
line, which its own logger writes for every socket.
"""

from __future__ import annotations

import logging
import math
import threading
import time

LOGGER = logging.getLogger("study.server.firewall")


class Notes:
    """Rate-limited warnings, one per key every ``every_s`` seconds (thread-safe)."""

    def __init__(self, *, every_s: float = 60.0, logger: logging.Logger = LOGGER) -> None:
        self.every_s = every_s
        self.logger = logger
        self._last: dict[str, float] = {}
        self._lock = threading.Lock()

    def due(self, key: str) -> bool:
        """True (and counted) when a line for ``key`` may be written now."""
        now = time.monotonic()
        with self._lock:
            last = self._last.get(key)
            if last is not None and now - last < self.every_s:
                return False
            self._last[key] = now
            return True

    def note(self, key: str, text: str) -> None:
        """Log ``text`` unless a line for ``key`` was written in the last ``every_s``."""
        if self.due(key):
            self.logger.warning("%s", text.encode("unicode_escape").decode("ascii")[:300])


class OpenLinesOnceAMinute(logging.Filter):
    """websockets logs "connection open" (INFO) for every socket: a flood of sockets would be a
    flood of lines. Let one through a minute."""

    def __init__(self, every_s: float = 60.0) -> None:
        super().__init__()
        self.every_s = every_s
        self._last = -math.inf

    def filter(self, record: logging.LogRecord) -> bool:
        if record.msg != "connection open":
            return True
        now = time.monotonic()
        if now - self._last < self.every_s:
            return False
        self._last = now
        return True

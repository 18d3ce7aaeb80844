"""Log lines a client can cause, at most one per kind every so often, never a payload.

A hostile client chooses how often it breaks a rule; the log must not grow with it.
:class:`Notes` lets one line per key through every ``every_s`` seconds (escaped, cut to 300
characters); :class:`OncePerMinute` does the same, without tracebacks, for every line
websockets' own logger writes per connection.
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


class OncePerMinute(logging.Filter):
    """For a library's logger that writes a line per connection (websockets: "connection
    open", "connection rejected (403 Forbidden)", "opening handshake failed" with a
    traceback, ...): one record of each kind a minute, never with a traceback."""

    def __init__(self, every_s: float = 60.0) -> None:
        super().__init__()
        self.every_s = every_s
        self._last: dict[str, float] = {}
        self._lock = threading.Lock()

    def filter(self, record: logging.LogRecord) -> bool:
        kind = str(record.msg)[:100]
        now = time.monotonic()
        with self._lock:
            if now - self._last.get(kind, -math.inf) < self.every_s:
                return False
            self._last[kind] = now
        record.exc_info, record.exc_text, record.stack_info = None, None, None
        return True

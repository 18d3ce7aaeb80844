"""Join codes and the throttle on guessing them.

A join code is ``CODE_LENGTH`` characters from an alphabet without look-alikes (no 0/O, 1/I/L,
2/Z, 5/S, 8/B, 6/G): 23**6 = 1.5e8 codes, typed case-insensitively with any spaces or dashes.
With at most ``per_client`` tries per connection, ``per_address`` per address and ``per_server``
from everywhere together in ``window_s`` seconds, a guesser needs about 1.5e8 / 60 per minute
(over four years, whatever number of machines it uses) to expect one hit among a handful of
open sessions; while guessing saturates the server's budget, honest tabs wait a minute too,
which the console shows.
"""

from __future__ import annotations

import secrets
import threading
import time
from collections import deque

ALPHABET = "ACDEFHJKMNPQRTUVWXY3479"
CODE_LENGTH = 6


def new_join_code(taken: set[str] | frozenset[str] = frozenset()) -> str:
    """A random code not in ``taken``."""
    while True:
        code = "".join(secrets.choice(ALPHABET) for _ in range(CODE_LENGTH))
        if code not in taken:
            return code


def normalize_code(text: str) -> str:
    """What the participant typed, as a code: upper case, spaces and dashes dropped, at most
    ``4 * CODE_LENGTH`` characters looked at."""
    return "".join(ch for ch in str(text)[: 4 * CODE_LENGTH].upper() if ch not in " -_\t")


class JoinThrottle:
    """Sliding-window limits on join attempts, per connection and per network address."""

    def __init__(
        self,
        *,
        per_client: int = 5,
        per_address: int = 20,
        per_server: int = 60,
        window_s: float = 60.0,
    ) -> None:
        self.per_client = per_client
        self.per_address = per_address
        self.per_server = per_server
        self.window_s = window_s
        self._tries: dict[tuple[str, object], deque[float]] = {}
        self._lock = threading.Lock()

    def allow(self, *, client: int, address: str) -> bool:
        """Count one attempt; False (and not counted) when either limit is reached."""
        now = time.monotonic()
        keys = (
            (("client", client), self.per_client),
            (("address", address), self.per_address),
            (("server", None), self.per_server),
        )
        with self._lock:
            windows = []
            for key, limit in keys:
                window = self._tries.setdefault(key, deque())
                while window and now - window[0] > self.window_s:
                    window.popleft()
                if len(window) >= limit:
                    return False
                windows.append(window)
            for window in windows:
                window.append(now)
            self._prune(now)
        return True

    def saturated(self) -> bool:
        """True while the server-wide budget is spent (someone is guessing codes)."""
        now = time.monotonic()
        with self._lock:
            window = self._tries.get(("server", None), deque())
            return sum(1 for t in window if now - t <= self.window_s) >= self.per_server

    def forget_client(self, client: int) -> None:
        with self._lock:
            self._tries.pop(("client", client), None)

    def _prune(self, now: float) -> None:
        """Drop empty or expired windows so the table stays as small as the live traffic."""
        if len(self._tries) < 1024:
            return
        stale = [k for k, w in self._tries.items() if not w or now - w[-1] > self.window_s]
        for key in stale:
            del self._tries[key]

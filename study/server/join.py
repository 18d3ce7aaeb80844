"""Join codes, rejoin tokens, and the throttle on guessing codes.

A join code is ``CODE_LENGTH`` characters from an alphabet without look-alikes (no 0/O, 1/I/L,
2/Z, 5/S, 8/B, 6/G): 23**6 = 1.5e8 codes, typed case-insensitively with any spaces or dashes.
A session's rejoin token (``TOKEN_LENGTH`` characters of the same alphabet, 23**20 ~ 2**90) is
given to the tab that holds it, which keeps it in a cookie: a reload or a reconnect presents
it at the door and rejoins without typing and without the throttle (it cannot be guessed).
Neither ever contains a word the participant must not see (the blinding guard would block the
message carrying it).

Typed codes are throttled: at most ``per_client`` tries per connection and ``per_address`` per
address in ``window_s`` seconds, and ``per_server`` from everywhere together -- but once that is
spent, an address with fewer than ``fresh_tries`` tries in the window may still try, so a
guesser's addresses use up the server's budget without keeping anybody else out. A guesser
needs about 1.5e8 / 60 tries per minute per address it owns (years) to expect one hit among a
handful of open sessions.
"""

from __future__ import annotations

import secrets
import threading
import time
from collections import deque
from collections.abc import Iterable

ALPHABET = "ACDEFHJKMNPQRTUVWXY3479"
CODE_LENGTH = 6
TOKEN_LENGTH = 20


def _random(length: int, avoid: Iterable[str]) -> str:
    words = [w.lower() for w in avoid]
    while True:
        text = "".join(secrets.choice(ALPHABET) for _ in range(length))
        if not any(w in text.lower() for w in words):
            return text


def new_join_code(
    taken: set[str] | frozenset[str] = frozenset(), *, avoid: Iterable[str] = ()
) -> str:
    """A random code not in ``taken`` and containing none of the words ``avoid``."""
    words = tuple(avoid)
    while True:
        code = _random(CODE_LENGTH, words)
        if code not in taken:
            return code


def new_token(*, avoid: Iterable[str] = ()) -> str:
    """A session's rejoin token (containing none of the words ``avoid``)."""
    return _random(TOKEN_LENGTH, avoid)


def normalize_code(text: str) -> str:
    """What the participant typed, as a code: upper case, spaces and dashes dropped, at most
    ``4 * CODE_LENGTH`` characters looked at."""
    return "".join(ch for ch in str(text)[: 4 * CODE_LENGTH].upper() if ch not in " -_\t")


class JoinThrottle:
    """Sliding-window limits on typed join codes, per connection, per address and in all."""

    def __init__(
        self,
        *,
        per_client: int = 5,
        per_address: int = 20,
        per_server: int = 60,
        fresh_tries: int = 3,
        window_s: float = 60.0,
    ) -> None:
        self.per_client = per_client
        self.per_address = per_address
        self.per_server = per_server
        self.fresh_tries = fresh_tries
        self.window_s = window_s
        self._tries: dict[tuple[str, object], deque[float]] = {}
        self._lock = threading.Lock()

    def allow(self, *, client: int, address: str) -> bool:
        """Count one attempt; False (and not counted) when a limit is reached."""
        now = time.monotonic()
        with self._lock:
            mine = self._window(("client", client), now)
            here = self._window(("address", address), now)
            everyone = self._window(("server", None), now)
            if len(mine) >= self.per_client or len(here) >= self.per_address:
                return False
            if len(everyone) >= self.per_server and len(here) >= self.fresh_tries:
                return False
            for window in (mine, here, everyone):
                window.append(now)
            self._prune(now)
        return True

    def _window(self, key: tuple[str, object], now: float) -> deque[float]:
        window = self._tries.setdefault(key, deque())
        while window and now - window[0] > self.window_s:
            window.popleft()
        return window

    def saturated(self) -> bool:
        """True while the server-wide budget is spent (someone is guessing codes)."""
        now = time.monotonic()
        with self._lock:
            return len(self._window(("server", None), now)) >= self.per_server

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

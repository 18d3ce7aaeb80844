"""How much a connection, and all connections together, may send.

* :class:`ConnectionRate`: at most ``rate_per_s`` messages a second per connection (burst
  ``burst``). The rate is counted when viser reads a message, not when it arrived (the kernel
  buffers it without a timestamp), so a backlog read at once after a stall of the event loop
  looks like a burst: a connection the server has not read from for ``t`` seconds may spend
  ``rate_per_s * t`` (up to ``backlog_s`` seconds' worth) on top of its burst -- what an honest
  page could have queued meanwhile. Twice the burst over the rate, or ``max_refused`` refused
  messages (forgiven at one a second), is not a page.
* :class:`MessageBudget`: a server-wide token bucket (``per_s``, burst ``burst``) shared by every
  connection; the excess is dropped before it is decoded, so many sockets each under its own
  rate cannot starve the control loop of the GIL. When the budget stays exhausted for
  ``evict_after_s`` one-second windows in a row, the address that sent most in the last one is
  named for eviction.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass


@dataclass
class ConnectionRate:
    """One connection's token bucket (times on the firewall's clock)."""

    tokens: float
    last: float
    refused: float = 0.0

    def spend(self, now: float, *, rate_per_s: float, burst: float, backlog_s: float) -> bool:
        """Count one message; False when the connection is far over its rate."""
        elapsed = now - self.last
        # credit for the time this connection went unread (a backlog), never clipped down
        cap = burst + rate_per_s * min(elapsed, backlog_s)
        self.tokens = min(max(cap, self.tokens), self.tokens + elapsed * rate_per_s)
        self.refused = max(0.0, self.refused - elapsed)  # forgiven at one a second
        self.last = now
        self.tokens -= 1.0
        return self.tokens >= -burst


class MessageBudget:
    """The server-wide budget (touched only on the server's event loop)."""

    def __init__(self, *, per_s: float, burst: float, evict_after_s: int, now: float) -> None:
        self.per_s = per_s
        self.burst = burst
        self.evict_after_s = evict_after_s
        self._tokens = burst
        self._t = now
        self._window_t = now
        self._window_sent: Counter[str] = Counter()
        self._window_dropped = 0
        self._over_windows = 0
        self.evict: str | None = None
        """The address whose connections are closed on their next message."""

    def take(self, address: str, now: float) -> bool:
        """Take one message from the bucket; False when it is empty."""
        if now - self._window_t >= 1.0:
            self._next_window(now)
        self._window_sent[address] += 1
        elapsed, self._t = now - self._t, now
        self._tokens = min(self.burst, self._tokens + elapsed * self.per_s)
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self._window_dropped += 1
        return False

    def _next_window(self, now: float) -> None:
        """Close out a one-second window: after ``evict_after_s`` windows in a row with
        drops, the address that sent most in the last one is named in ``evict``."""
        self._over_windows = self._over_windows + 1 if self._window_dropped else 0
        self.evict = None
        if self._over_windows >= self.evict_after_s and self._window_sent:
            self.evict = self._window_sent.most_common(1)[0][0]
            self._over_windows = 0
        self._window_sent.clear()
        self._window_dropped = 0
        self._window_t = now

"""How much one connection may send.

:class:`ConnectionRate`: at most ``rate_per_s`` messages a second per connection (burst
``burst``). The rate is counted when viser reads a message, not when it arrived (the kernel
buffers it without a timestamp), so a backlog read at once after a stall of the event loop
looks like a burst: a connection the server has not read from for ``t`` seconds may spend
``rate_per_s * t`` (up to ``backlog_s`` seconds' worth) on top of its burst -- what an honest
page could have queued meanwhile. Twice the burst over the rate, or ``max_refused`` refused
messages (forgiven at one a second), is not a page.
"""

from __future__ import annotations

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

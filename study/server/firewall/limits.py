"""How much one connection may send.

:class:`ConnectionRate`: at most ``rate_per_s`` messages a second per connection (burst
``burst``). The rate is counted when viser reads a message, not when it arrived (the kernel
buffers it without a timestamp), so a backlog read at once after a stall of the event loop
looks like a burst: a connection the server has not read from for ``t`` seconds may spend
``rate_per_s * t`` (up to ``backlog_s`` seconds' worth) on top of its burst -- what an honest
page could have queued meanwhile. Twice the burst over the rate, or ``max_refused`` refused
messages (forgiven at one a second), is not a page.

:class:`FrameBudget`: what one connection may send below a message, where the message rules
never look. A browser sends each message in one frame and never pings; the websocket library
keeps every frame of an unfinished message (its size limit counts bytes, so empty fragments
never reach it) and answers every ping. So a message may come in at most ``max_fragments``
frames and pings at ``pings_per_s`` (burst ``ping_burst``); past either the connection closes.
"""

from __future__ import annotations

from dataclasses import dataclass, field


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


@dataclass
class FrameBudget:
    """One connection's frames below the message level (module docstring)."""

    max_fragments: int
    pings_per_s: float
    ping_burst: float
    last: float
    fragments: int = 0
    ping_tokens: float = field(init=False)

    def __post_init__(self) -> None:
        self.ping_tokens = self.ping_burst

    def data(self, *, fin: bool) -> str | None:
        """Count a data frame (``fin``: it ends its message); the reason to close, or ``None``."""
        self.fragments = 0 if fin else self.fragments + 1
        if self.fragments >= self.max_fragments:
            return f"a message in more than {self.max_fragments} frames"
        return None

    def ping(self, now: float) -> str | None:
        """Count a ping at time ``now``; the reason to close, or ``None``."""
        self.ping_tokens = min(
            self.ping_burst, self.ping_tokens + (now - self.last) * self.pings_per_s
        )
        self.last = now
        self.ping_tokens -= 1.0
        if self.ping_tokens < 0.0:
            return f"more than {self.pings_per_s:g} pings a second"
        return None

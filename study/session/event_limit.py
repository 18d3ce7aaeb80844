"""``EventLimiter``: a per-kind cap on how fast a session's own events reach the store.

Every event is one fsync'd transaction. Events a client can trigger at will -- a rejected
input, a refused join, a reconnect -- would otherwise let one hostile or broken tab write
thousands of rows a second (10,000 NaN poses once added 10,200 rows) and take disk time from
the sample writer. Each kind gets a token bucket: ``burst`` events at once, then ``rate_per_s``
on average. An event over the limit is not written but counted, and the next event of that kind
that is written carries ``"suppressed": k`` (how many were dropped since the last one written);
``pending()`` hands over what is still counted when the session ends or closes. The count is never
lost, only the repeated payloads.

The engine's own events (trial start/end, answers, pause, resume, ...) are written inside their
transitions and never pass through here.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

DEFAULT_BURST = 10
DEFAULT_RATE_PER_S = 1.0


@dataclass
class _Bucket:
    tokens: float
    at: float
    suppressed: int = 0


class EventLimiter:
    """Token buckets per event kind (see module docstring). Not thread-safe: the session calls
    it under its own lock."""

    def __init__(
        self,
        *,
        burst: int = DEFAULT_BURST,
        rate_per_s: float = DEFAULT_RATE_PER_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if burst < 1 or not rate_per_s > 0:
            raise ValueError(f"burst must be >= 1 and rate_per_s > 0, got {burst}, {rate_per_s}")
        self.burst = burst
        self.rate_per_s = rate_per_s
        self._clock = clock
        self._buckets: dict[str, _Bucket] = {}

    def admit(self, kind: str) -> int | None:
        """``None`` if an event of ``kind`` must not be written now (it is counted); else the
        number suppressed since the last one written, which the written event should carry."""
        now = self._clock()
        bucket = self._buckets.get(kind)
        if bucket is None:
            bucket = self._buckets[kind] = _Bucket(tokens=float(self.burst), at=now)
        bucket.tokens = min(float(self.burst), bucket.tokens + (now - bucket.at) * self.rate_per_s)
        bucket.at = now
        if bucket.tokens < 1.0:
            bucket.suppressed += 1
            return None
        bucket.tokens -= 1.0
        suppressed, bucket.suppressed = bucket.suppressed, 0
        return suppressed

    def restore(self, kind: str, suppressed: int) -> None:
        """Put back the count an admitted event was to carry, when writing it failed."""
        if suppressed:
            self._buckets[kind].suppressed += suppressed

    def pending(self) -> dict[str, int]:
        """Kinds with suppressed events not yet reported, and how many."""
        return {k: b.suppressed for k, b in self._buckets.items() if b.suppressed}

    def reported(self, counts: dict[str, int]) -> None:
        """``counts`` (from ``pending``) were written to the store: stop counting them."""
        for kind, n in counts.items():
            self._buckets[kind].suppressed -= n


__all__ = ["DEFAULT_BURST", "DEFAULT_RATE_PER_S", "EventLimiter"]

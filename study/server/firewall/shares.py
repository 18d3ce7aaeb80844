"""Fair shares of the server's time for the connections that hold no session.

A bound tab (a session's) is never slowed or dropped by anything here. Everything else shares:

* :class:`FairShares`: unbound connections share ``per_s`` messages a second, split evenly
  among the addresses that sent in the last ``window_s`` seconds (an address's connections
  share its part); a message over its address's share is not dropped but read later
  (``delay``): the connection waits, its frames stay in the kernel's buffer and its sender
  blocks, so a flood costs the server nothing and a join code typed behind it still arrives.
* :class:`ByteBudget`: the bytes one bound tab may send, far above what a page sends (its
  poses and key states are a few KiB a second; a free-text answer typed out to 8,000
  characters at ten keys a second, each key sending the whole value, is 80 KiB a second);
  past it the tab's reads wait as above. Eight thousand characters 190 times a second from
  one tab once took the other sessions' control loops to 0-16 ticks in a 0.25-s window.
* :class:`AcceptGate`: new connections (or new tabs) per address, ``per_s`` a second with a
  burst of ``burst``. When all addresses together exceed ``total_per_s``, only an address that
  has been quiet (at least half its burst left) gets in: a reconnect storm from a few
  addresses cannot keep a new tab out.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass


@dataclass
class _Bucket:
    tokens: float
    last: float


SWEEP_EVERY_S = 1.0
"""Addresses are looked through for idle ones at most this often: a look at every new address
made each one cost a scan of them all (0.5-2.3 ms a connect from 1,000-5,000 new addresses a
second, an attacker's pass found)."""
MAX_ADDRESSES = 65_536
"""Addresses remembered at most: past it the half seen longest ago is forgotten at once (they
start again with a full allowance, as a new address does)."""


class _Forgetting:
    """When to forget addresses: idle ones once more than ``soft`` are known (at most every
    ``SWEEP_EVERY_S``), and the oldest half past ``MAX_ADDRESSES``; amortised O(1) a call."""

    def __init__(self, *, soft: int) -> None:
        self.soft = soft
        self._swept = float("-inf")

    def sweep(self, buckets: dict[str, _Bucket], now: float, *, idle_s: float) -> None:
        n = len(buckets)
        if n > self.soft and now - self._swept >= SWEEP_EVERY_S:
            self._swept = now
            for address in [a for a, b in buckets.items() if now - b.last > idle_s]:
                del buckets[address]
        if len(buckets) > MAX_ADDRESSES:
            for address in list(itertools.islice(buckets, len(buckets) // 2)):
                del buckets[address]


class FairShares:
    """Message shares of the unbound connections (used on the server's event loop only)."""

    def __init__(self, *, per_s: float = 400.0, burst_s: float = 1.0, window_s: float = 2.0):
        self.per_s = per_s
        self.burst_s = burst_s
        self.window_s = window_s
        self._buckets: dict[str, _Bucket] = {}
        self._forgetting = _Forgetting(soft=256)
        self.delayed = 0
        """Messages that waited for their address's share."""

    def share(self, now: float) -> float:
        """Messages a second each active address may send now."""
        active = sum(1 for b in self._buckets.values() if now - b.last <= self.window_s)
        return self.per_s / max(1, active)

    def delay(self, address: str, now: float, *, cost: float = 1.0) -> float:
        """Seconds the next message of ``address`` must wait to stay within its share (0: go);
        ``cost``: what it counts as (a long message counts as several)."""
        self._forget(now)
        bucket = self._buckets.get(address)
        share = self.share(now) if bucket is not None else self.per_s / (1 + len(self._buckets))
        cap = share * self.burst_s
        if bucket is None:
            bucket = self._buckets[address] = _Bucket(tokens=cap, last=now)
        bucket.tokens = min(cap, bucket.tokens + (now - bucket.last) * share)
        bucket.last = now
        bucket.tokens -= cost
        if bucket.tokens >= 0.0:
            return 0.0
        self.delayed += 1
        return -bucket.tokens / share

    def _forget(self, now: float) -> None:
        self._forgetting.sweep(self._buckets, now, idle_s=self.window_s)


class ByteBudget:
    """Bytes a second of one connection, ``per_s`` after a burst of ``burst``."""

    def __init__(self, *, per_s: float, burst: float, now: float) -> None:
        self.per_s = per_s
        self.burst = burst
        self._bucket = _Bucket(tokens=burst, last=now)

    def delay(self, size: int, now: float) -> float:
        """Seconds the connection waits after a message of ``size`` bytes (0: go on)."""
        b = self._bucket
        b.tokens = min(self.burst, b.tokens + (now - b.last) * self.per_s) - size
        b.last = now
        return 0.0 if b.tokens >= 0.0 else -b.tokens / self.per_s


class AcceptGate:
    """New connections per address (used on the server's event loop only)."""

    def __init__(
        self, *, per_s: float = 5.0, burst: float = 30.0, total_per_s: float = 200.0
    ) -> None:
        self.per_s = per_s
        self.burst = burst
        self.total_per_s = total_per_s
        self._buckets: dict[str, _Bucket] = {}
        self._forgetting = _Forgetting(soft=4096)
        self._total: _Bucket | None = None
        self.refused = 0

    def allow(self, address: str, now: float) -> bool:
        """Count one new connection from ``address``; False when it must be turned away."""
        bucket = self._buckets.get(address)
        if bucket is None:
            self._forgetting.sweep(self._buckets, now, idle_s=self.burst / self.per_s)
            bucket = self._buckets[address] = _Bucket(tokens=self.burst, last=now)
        bucket.tokens = min(self.burst, bucket.tokens + (now - bucket.last) * self.per_s)
        bucket.last = now
        total = self._total
        if total is None:
            total = self._total = _Bucket(tokens=2 * self.total_per_s, last=now)
        total.tokens = min(
            2 * self.total_per_s, total.tokens + (now - total.last) * self.total_per_s
        )
        total.last = now
        quiet = bucket.tokens >= self.burst / 2
        if bucket.tokens < 1.0 or (total.tokens < 1.0 and not quiet):
            self.refused += 1
            return False
        bucket.tokens -= 1.0
        total.tokens = max(0.0, total.tokens - 1.0)
        return True

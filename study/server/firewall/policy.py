"""``Firewall``: the rules for one viser server's port, and what they refused.

* At the door (``process_request``, installed by ``hooks.hardened_serve``): a message-size
  limit of ``max_bytes`` from the handshake on; a websocket whose ``Origin`` is another site's
  is refused; so are more than ``max_connections_per_address`` / ``max_connections`` open
  websockets, a repeated ``Host``/``Origin``/``Upgrade`` header and a ``Host`` carrying userinfo
  or a path (403, never 500); a request for a file that cannot even be named gets 404.
* Per frame, before viser (``screened_recv``): a text frame closes its connection with 1003;
  the server-wide :class:`~study.server.firewall.limits.MessageBudget` drops the excess before
  it is decoded and closes the connections of the address it names for eviction.
* Per message (``admit`` and ``screen``, called by the decoder hook): the per-connection
  :class:`~study.server.firewall.limits.ConnectionRate`, then ``rules.screen``.

A refused message is counted under a fixed reason (never a name the client chose) and logged
as a one-line summary at most once per reason every ``log_every_s`` seconds. A connection
closed for what it sent (:class:`ConnectionFlood`) closes with a policy code and no traceback.
"""

from __future__ import annotations

import asyncio
import http
import threading
import time
import weakref
from collections import Counter
from collections.abc import Callable, Iterable
from typing import Any
from urllib.parse import urlsplit

import viser
from websockets.datastructures import Headers
from websockets.http11 import Response

from study.server.firewall import rules
from study.server.firewall.hooks import remote_host
from study.server.firewall.limits import ConnectionRate, MessageBudget
from study.server.firewall.notes import LOGGER, Notes
from study.server.firewall.rules import (
    LOOPBACK_NAMES,
    MAX_MESSAGE_BYTES,
    MAX_POSITION_M,
    PARTICIPANT_TYPES,
    SHARE_TYPES,
    ConnectionFlood,
    Dropped,
)

BUDGET = "over the server's message budget"
REPEATED_HEADERS = ("Host", "Origin", "Upgrade")


class Firewall:
    """The rules for one viser server's incoming messages, and what they refused."""

    def __init__(
        self,
        *,
        allowed: Iterable[str] | None = PARTICIPANT_TYPES,
        allow_share: bool = False,
        max_bytes: int = MAX_MESSAGE_BYTES,
        max_position_m: float = MAX_POSITION_M,
        log_every_s: float = 60.0,
        on_drop: Callable[[str], None] | None = None,
        rate_per_s: float = 200.0,
        burst: float = 400.0,
        max_refused: int = 200,
        max_connections: int = 64,
        max_connections_per_address: int = 8,
        check_origin: bool = True,
        loopback_only: bool = False,
        backlog_s: float = 10.0,
        budget_per_s: float | None = 1000.0,
        budget_burst: float = 2000.0,
        evict_after_s: int = 2,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.allowed = None if allowed is None else frozenset(allowed) - SHARE_TYPES
        if allow_share and self.allowed is not None:
            self.allowed |= SHARE_TYPES
        self.allow_share = allow_share
        self.max_bytes = max_bytes
        self.max_position_m = max_position_m
        self.on_drop = on_drop
        self.rate_per_s = rate_per_s
        self.burst = burst
        self.max_refused = max_refused
        self.max_connections = max_connections
        self.max_connections_per_address = max_connections_per_address
        self.check_origin = check_origin
        self.loopback_only = loopback_only
        self.backlog_s = backlog_s
        self._clock = clock  # of the rate limits (a test's own clock)
        self.budget = (
            None
            if budget_per_s is None
            else MessageBudget(
                per_s=budget_per_s, burst=budget_burst, evict_after_s=evict_after_s, now=clock()
            )
        )
        self.notes = Notes(every_s=log_every_s)
        self.passed = 0
        self.dropped: Counter[str] = Counter()
        self.closed_connections = 0
        self.refused_connections: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._server: viser.ViserServer | None = None
        # per connection (its message-reading task)
        self._rates: weakref.WeakKeyDictionary[asyncio.Task[Any], ConnectionRate] = (
            weakref.WeakKeyDictionary()
        )

    def attach(self, server: viser.ViserServer) -> None:
        """The server whose connections the door counts (``hooks.install`` calls this)."""
        self._server = server

    # -- at the door -----------------------------------------------------------------------------
    def process_request(self, inner: Callable[..., Any] | None) -> Callable[..., Any]:
        """Wrap viser's HTTP handler: origin and connection checks, and 404 for bad paths."""

        def handle(connection: Any, request: Any) -> Any:
            repeated = [h for h in REPEATED_HEADERS if len(request.headers.get_all(h)) > 1]
            if repeated:
                return self._forbid(f"a repeated {repeated[0]} header")
            if request.headers.get("Upgrade", "").lower() == "websocket":
                problem = self._door_problem(connection, request)
                if problem is not None:
                    return self._forbid(problem)
            if inner is None:
                return None
            try:
                return inner(connection, request)
            except OSError:  # e.g. a path too long to be a file name
                return Response(http.HTTPStatus.NOT_FOUND, "NOT FOUND", Headers(), b"")

        return handle

    def _forbid(self, problem: str) -> Response:
        self.notes.note("connection refused", problem)
        with self._lock:
            self.refused_connections[problem.split(" (")[0]] += 1
        return Response(http.HTTPStatus.FORBIDDEN, "Forbidden", Headers(), b"")

    def _door_problem(self, connection: Any, request: Any) -> str | None:
        host = request.headers.get("Host", "")
        if any(ch in host for ch in "@/\\?#"):  # userinfo or a path: not a host name
            return "a malformed Host header"
        if self.loopback_only and urlsplit(f"//{host}").hostname not in LOOPBACK_NAMES:
            return "a name other than this machine's (DNS rebinding)"
        if self.check_origin:
            origin = request.headers.get("Origin")
            if origin is not None and urlsplit(origin).netloc.lower() != host.lower():
                return "another site's page (origin check)"
        server = self._server
        live = dict(server._websock_server._live_connections) if server is not None else {}
        if len(live) >= self.max_connections:
            return f"too many connections ({len(live)})"
        address = remote_host(connection)
        same = sum(1 for c in live.values() if remote_host(c) == address)
        if same >= self.max_connections_per_address:
            return f"too many connections from one address ({same})"
        return None

    # -- per message -----------------------------------------------------------------------------
    def admit(self) -> None:
        """Count one message of the current connection; raise :class:`ConnectionFlood` to
        close a connection far over its rate or with too many refused messages."""
        task = asyncio.current_task()
        if task is None:
            return
        now = self._clock()
        rate = self._rates.get(task)
        if rate is None:
            rate = self._rates[task] = ConnectionRate(self.burst, now)
        within = rate.spend(
            now, rate_per_s=self.rate_per_s, burst=self.burst, backlog_s=self.backlog_s
        )
        if not within:  # twice the burst over the rate: not a page
            self._closing(f"more than {self.rate_per_s:g} messages a second")

    def count_refusal(self) -> None:
        task = asyncio.current_task()
        rate = self._rates.get(task) if task is not None else None
        if rate is not None:
            rate.refused += 1
            if rate.refused > self.max_refused:
                self._closing(f"more than {self.max_refused} refused messages")

    def _closing(self, why: str, *, code: int = 1008) -> None:
        with self._lock:
            self.closed_connections += 1
        self.notes.note("connection closed", f"closed a connection that sent {why}")
        raise ConnectionFlood(why, code=code)

    # -- per frame, before viser ---------------------------------------------------------------
    def screened_recv(self, connection: Any) -> Callable[..., Any]:
        """``connection.recv`` behind the text-frame rule and the server-wide budget."""
        recv = connection.recv
        address = remote_host(connection)

        async def screened(*args: Any, **kwargs: Any) -> Any:
            while True:
                raw = await recv(*args, **kwargs)
                if not isinstance(raw, bytes):
                    self.refuse("text frame (viser speaks binary)")
                    self._closing("a text frame", code=1003)
                if self._within_budget(address):
                    return raw

        return screened

    def _within_budget(self, address: str) -> bool:
        """Take one message from the server-wide budget; False (counted) when it is empty."""
        budget = self.budget
        if budget is None:
            return True
        now = self._clock()
        if budget.take(address, now):
            return True
        if address == budget.evict:
            self._closing("its share of a flood over the server's message budget")
        self.refuse(f"{BUDGET} ({budget.per_s:g} a second)")
        return False

    def screen(self, raw: bytes) -> str | None:
        """``None`` when ``raw`` may be decoded, else the reason it is refused."""
        return rules.screen(
            raw,
            max_bytes=self.max_bytes,
            allowed=self.allowed,
            allow_share=self.allow_share,
            max_position_m=self.max_position_m,
        )

    def refuse(self, reason: str) -> Dropped:
        key = reason.split(":")[0].split(" (")[0]
        with self._lock:
            self.dropped[key] += 1
            count = self.dropped[key]
        if self.notes.due(key):
            LOGGER.warning("refused an incoming message: %s (%d refused so far)", reason, count)
        if self.on_drop is not None:
            try:
                self.on_drop(reason)
            except Exception:
                LOGGER.exception("firewall on_drop callback failed")
        return Dropped(reason=reason)

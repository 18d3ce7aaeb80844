"""``Firewall``: the rules for one viser server's port, and what they refused.

* Before a request is read (``accepts``): new TCP connections per address
  (``shares.AcceptGate``, generous: a page load needs two); over it, the socket is reset.
* At the door (``process_request``, for a websocket handshake): a message-size limit of
  ``max_bytes`` from the handshake on; refused with 403 (never 500): another site's ``Origin``,
  a repeated ``Host``/``Origin``/``Upgrade`` header, a ``Host`` carrying userinfo or a path, a
  client that does not speak this server's viser version, a new tab (no rejoin token) over its
  address's rate of new tabs (a second ``AcceptGate``, strict: each tab costs the server about
  10 ms of work), and no slot left (``slots.Slots``: per address and in all, shared fairly, with
  room kept for tabs that present a session's rejoin token). A request for a file that cannot
  even be named gets 404.
* Per frame, before viser (``screened_recv``): a text frame closes its connection with 1003;
  an unbound connection waits for its address's share (``shares.FairShares``; a message counts
  once per KiB begun); a bound tab waits only past ``bound_bytes_per_s`` (``shares.ByteBudget``,
  far above what a page sends).
* Per message (``admit`` and ``screen``, called by the decoder hook): the per-connection
  :class:`~study.server.firewall.limits.ConnectionRate`, then ``rules.screen``; GUI text
  values up to ``rules.MAX_GUI_TEXT`` characters from a bound tab (a free-text answer), up to
  ``rules.MAX_STRING`` from any other (a join code, a link's IDs).
* Every second, slots that never sent a message, or sat idle on the join screen too long, are
  closed.

A refused message is counted under a fixed reason (never a name the client chose) and logged
as a one-line summary at most once per reason every ``log_every_s`` seconds; one refused from a
bound tab is reported to ``on_bound_drop`` (the session records it). A connection closed for
what it sent (:class:`ConnectionFlood`) closes with a policy code and no traceback.
"""

from __future__ import annotations

import asyncio
import contextlib
import http
import threading
import time
import weakref
from collections import Counter
from collections.abc import Callable, Iterable
from http.cookies import CookieError, SimpleCookie
from typing import Any
from urllib.parse import urlsplit

import viser
from websockets.datastructures import Headers
from websockets.http11 import Response

from study.server.firewall import rules
from study.server.firewall.hooks import remote_host
from study.server.firewall.limits import ConnectionRate
from study.server.firewall.notes import LOGGER, Notes
from study.server.firewall.rules import (
    LOOPBACK_NAMES,
    MAX_GUI_TEXT,
    MAX_MESSAGE_BYTES,
    MAX_POSITION_M,
    MAX_STRING,
    PARTICIPANT_TYPES,
    SHARE_TYPES,
    ConnectionFlood,
    Dropped,
)
from study.server.firewall.shares import AcceptGate, ByteBudget, FairShares
from study.server.firewall.slots import Slot, Slots
from study.server.forwarded import Network, accepted_hosts, client_address, is_trusted

REPEATED_HEADERS = ("Host", "Origin", "Upgrade")
REJOIN_COOKIE = "study-rejoin"
"""The cookie a bound tab keeps its session's rejoin token in (sent with its next handshake)."""
SWEEP_EVERY_S = 1.0


class Firewall:
    """The rules for one viser server's incoming connections and messages, and what they
    refused."""

    def __init__(
        self,
        *,
        allowed: Iterable[str] | None = PARTICIPANT_TYPES,
        allow_share: bool = False,
        max_bytes: int = MAX_MESSAGE_BYTES,
        max_position_m: float = MAX_POSITION_M,
        log_every_s: float = 60.0,
        on_drop: Callable[[str], None] | None = None,
        on_bound_drop: Callable[[int, str], None] | None = None,
        rate_per_s: float = 200.0,
        burst: float = 400.0,
        max_refused: int = 200,
        max_connections: int = 64,
        max_connections_per_address: int = 8,
        greet_timeout_s: float = 15.0,
        idle_timeout_s: float | None = 600.0,
        check_origin: bool = True,
        loopback_only: bool = False,
        backlog_s: float = 10.0,
        shares_per_s: float | None = 400.0,
        bound_bytes_per_s: float | None = 128 * 1024,
        bound_bytes_burst: float = 1024 * 1024,
        accept_per_s: float | None = 1.0,
        accept_burst: float = 12.0,
        accept_total_per_s: float = 40.0,
        new_tabs_per_s: float | None = 0.2,
        new_tabs_burst: float = 6.0,
        new_tabs_total_per_s: float = 2.0,
        trusted_proxies: tuple[Network, ...] = (),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.allowed = None if allowed is None else frozenset(allowed) - SHARE_TYPES
        if allow_share and self.allowed is not None:
            self.allowed |= SHARE_TYPES
        self.allow_share = allow_share
        self.max_bytes = max_bytes
        self.max_position_m = max_position_m
        self.on_drop = on_drop
        self.on_bound_drop = on_bound_drop
        self.rate_per_s = rate_per_s
        self.burst = burst
        self.max_refused = max_refused
        self.check_origin = check_origin
        self.loopback_only = loopback_only
        self.backlog_s = backlog_s
        self.trusted_proxies = trusted_proxies
        """Peers whose forwarded client address counts (``study.server.forwarded``)."""
        self._clock = clock  # of the rate limits and slots (a test's own clock)
        self.slots = Slots(
            max_total=max_connections,
            max_per_address=max_connections_per_address,
            greet_timeout_s=greet_timeout_s,
            idle_timeout_s=idle_timeout_s,
        )
        self.shares = None if shares_per_s is None else FairShares(per_s=shares_per_s)
        self.bound_bytes_per_s = bound_bytes_per_s
        self.bound_bytes_burst = bound_bytes_burst
        self.slowed = 0
        """Reads of a bound tab that waited for its byte budget."""
        self.gate = (
            None
            if accept_per_s is None
            else AcceptGate(per_s=accept_per_s, burst=accept_burst, total_per_s=accept_total_per_s)
        )
        self.tab_gate = (
            None
            if new_tabs_per_s is None
            else AcceptGate(
                per_s=new_tabs_per_s, burst=new_tabs_burst, total_per_s=new_tabs_total_per_s
            )
        )
        self.rejoin_token: Callable[[str], str | None] = lambda _value: None
        """Set by the server: the session token a rejoin cookie's value proves, else ``None``."""
        self.notes = Notes(every_s=log_every_s)
        self.page_filter: Callable[[Any, Any], Any] | None = None
        """Rewrites viser's HTTP responses, ``(request, response) -> response`` (the study
        server's page head: ``study.server.page_head``)."""
        self.passed = 0
        self.dropped: Counter[str] = Counter()
        self.closed_connections = 0
        self.refused_connections: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._server: viser.ViserServer | None = None
        self._sweeper: asyncio.Task[None] | None = None
        # the slot of each connection's message-reading task
        self._task_slots: weakref.WeakKeyDictionary[asyncio.Task[Any], Slot] = (
            weakref.WeakKeyDictionary()
        )

    @property
    def max_connections(self) -> int:
        return self.slots.max_total

    @property
    def max_connections_per_address(self) -> int:
        return self.slots.max_per_address

    # -- addresses ---------------------------------------------------------------------------
    def client_host(self, connection: Any, headers: Any = None) -> str:
        """The address limits and logs use for ``connection`` (the one place that says): its
        peer's, or behind a trusted proxy the client's (``study.server.forwarded``)."""
        if headers is None:
            request = getattr(connection, "request", None)
            headers = getattr(request, "headers", None)
        return client_address(remote_host(connection), headers, trusted=self.trusted_proxies)

    # -- lifetime ----------------------------------------------------------------------------
    def attach(self, server: viser.ViserServer) -> None:
        """Watch ``server``'s connections (``hooks.install`` calls this): start the sweeper."""
        self._server = server
        loop = server._websock_server._background_event_loop
        if loop is not None:
            asyncio.run_coroutine_threadsafe(self._start_sweeper(), loop).result(timeout=5)

    def detach(self) -> None:
        server, self._server = self._server, None
        loop = None if server is None else server._websock_server._background_event_loop
        sweeper = self._sweeper
        if loop is not None and sweeper is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(sweeper.cancel)

    async def _start_sweeper(self) -> None:
        self._sweeper = asyncio.get_running_loop().create_task(self._sweep())

    async def _sweep(self) -> None:
        while True:
            await asyncio.sleep(SWEEP_EVERY_S)
            for slot in self.slots.overdue(self._clock()):
                why = "no first message" if not slot.greeted else "idle on the join screen"
                self.notes.note("timed out", f"closed a connection: {why}")
                self._close(slot, 1001)

    @staticmethod
    def _close(slot: Slot, code: int) -> None:
        connection = slot.connection
        if connection is not None and hasattr(connection, "close"):
            asyncio.get_running_loop().create_task(connection.close(code, ""))

    # -- before the request ------------------------------------------------------------------
    def accepts(self, peer: str) -> bool:
        """A new TCP connection from ``peer``: False to reset it before reading anything."""
        gate = self.gate
        if (
            gate is None
            or is_trusted(peer, self.trusted_proxies)
            or gate.allow(peer, self._clock())
        ):
            return True  # a trusted proxy carries every client: the door counts them by address
        self.notes.note("accept gate", f"reset new connections from {peer}: too many too fast")
        with self._lock:
            self.refused_connections["too many new connections from one address"] += 1
        return False

    def connection_lost(self, connection: Any) -> None:
        """A connection is gone (its slot is free)."""
        self.slots.remove(connection)

    # -- at the door -------------------------------------------------------------------------
    def process_request(self, inner: Callable[..., Any] | None) -> Callable[..., Any]:
        """Wrap viser's HTTP handler: origin and slot checks, and 404 for bad paths."""

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
                response = inner(connection, request)
            except OSError:  # e.g. a path too long to be a file name
                return Response(http.HTTPStatus.NOT_FOUND, "NOT FOUND", Headers(), b"")
            page_filter = self.page_filter
            return response if page_filter is None else page_filter(request, response)

        return handle

    def _forbid(self, problem: str) -> Response:
        self.notes.note("connection refused", problem)
        with self._lock:
            self.refused_connections[problem.split(" (")[0]] += 1
        return Response(http.HTTPStatus.FORBIDDEN, "Forbidden", Headers(), b"")

    def _door_problem(self, connection: Any, request: Any) -> str | None:
        headers = request.headers
        host = headers.get("Host", "")
        if any(ch in host for ch in "@/\\?#"):  # userinfo or a path: not a host name
            return "a malformed Host header"
        if self.loopback_only and urlsplit(f"//{host}").hostname not in LOOPBACK_NAMES:
            return "a name other than this machine's (DNS rebinding)"
        if self.check_origin:
            origin = headers.get("Origin")
            hosts = accepted_hosts(remote_host(connection), headers, trusted=self.trusted_proxies)
            if origin is not None and urlsplit(origin).netloc.lower() not in hosts:
                return "another site's page (origin check)"
        offered = {
            p.strip() for v in headers.get_all("Sec-WebSocket-Protocol") for p in v.split(",")
        }
        if f"viser-v{viser.__version__}" not in offered:
            return "a client that does not speak this server's version"
        token = self.rejoin_token(_cookie(headers, REJOIN_COOKIE))
        if token is not None and not self.slots.room_for_token(token):
            token = None  # another tab of the same browser: a new tab (Slots.room_for_token)
        address = self.client_host(connection, headers)
        now = self._clock()
        if token is None and self.tab_gate is not None and not self.tab_gate.allow(address, now):
            return "too many new tabs from one address"
        evict, problem = self.slots.admit(connection, address, now=now, token=token)
        if problem is not None:
            return problem
        if evict is not None:
            self.notes.note(
                "evicted", f"closed an unbound connection of {evict.address} for a newcomer"
            )
            self._close(evict, 1013)
        return None

    # -- sessions ----------------------------------------------------------------------------
    def bind(self, client_id: int, bound: bool = True) -> None:
        """The tab ``client_id`` now holds a session (``bound``) or no longer does: a bound tab
        is never slowed, and what the rules refuse from it is reported to ``on_bound_drop``."""
        server = self._server
        if server is None:
            return
        connection = server._websock_server._live_connections.get(client_id)
        slot = self.slots.get(connection) if connection is not None else None
        if slot is not None:
            slot.bound, slot.client_id = bound, client_id

    def token_of(self, client_id: int) -> str | None:
        """The rejoin token tab ``client_id`` presented at the door (``None``: none, or none
        that an open session issued)."""
        server = self._server
        if server is None:
            return None
        connection = server._websock_server._live_connections.get(client_id)
        slot = self.slots.get(connection) if connection is not None else None
        return None if slot is None else slot.token

    # -- per frame, before viser -------------------------------------------------------------
    def screened_recv(self, connection: Any) -> Callable[..., Any]:
        """``connection.recv`` behind the text-frame rule and the fair shares."""
        recv = connection.recv
        fallback = Slot(address=self.client_host(connection), opened=self._clock())

        async def screened(*args: Any, **kwargs: Any) -> Any:
            slot = self.slots.get(connection) or fallback
            task = asyncio.current_task()
            if task is not None:
                self._task_slots[task] = slot
            raw = await recv(*args, **kwargs)
            slot.last_seen = now = self._clock()
            if not isinstance(raw, bytes):
                self.refuse("text frame (viser speaks binary)")
                self._closing("a text frame", code=1003)
            wait = 0.0
            if not slot.bound and self.shares is not None:
                wait = self.shares.delay(slot.address, now, cost=1 + len(raw) // 1024)
            elif slot.bound and self.bound_bytes_per_s is not None:
                if slot.budget is None:
                    per_s, burst = self.bound_bytes_per_s, self.bound_bytes_burst
                    slot.budget = ByteBudget(per_s=per_s, burst=burst, now=now)
                wait = slot.budget.delay(len(raw), now)
                self.slowed += wait > 0.0
            if wait > 0.0:
                await asyncio.sleep(wait)
            return raw

        return screened

    # -- per message -------------------------------------------------------------------------
    def _slot(self) -> Slot | None:
        """The slot of the connection whose message is being handled (``None`` off the loop)."""
        try:
            task = asyncio.current_task()
        except RuntimeError:
            return None
        return None if task is None else self._task_slots.get(task)

    def admit(self) -> None:
        """Count one message of the current connection; raise :class:`ConnectionFlood` to
        close a connection far over its rate or with too many refused messages."""
        slot = self._slot()
        if slot is None:
            return
        now = self._clock()
        if slot.rate is None:
            slot.rate = ConnectionRate(self.burst, now)
        within = slot.rate.spend(
            now, rate_per_s=self.rate_per_s, burst=self.burst, backlog_s=self.backlog_s
        )
        if not within:  # twice the burst over the rate: not a page
            self._closing(f"more than {self.rate_per_s:g} messages a second")

    def admitted(self) -> None:
        """The current connection's message passed every rule (its slot is greeted)."""
        self.passed += 1
        slot = self._slot()
        if slot is not None:
            slot.greeted = True

    def count_refusal(self) -> None:
        slot = self._slot()
        if slot is not None and slot.rate is not None:
            slot.rate.refused += 1
            if slot.rate.refused > self.max_refused:
                self._closing(f"more than {self.max_refused} refused messages")

    def _closing(self, why: str, *, code: int = 1008) -> None:
        with self._lock:
            self.closed_connections += 1
        self.notes.note("connection closed", f"closed a connection that sent {why}")
        raise ConnectionFlood(why, code=code)

    def screen(self, raw: bytes) -> str | None:
        """``None`` when ``raw`` may be decoded, else the reason it is refused."""
        slot = self._slot()
        return rules.screen(
            raw,
            max_bytes=self.max_bytes,
            allowed=self.allowed,
            allow_share=self.allow_share,
            max_position_m=self.max_position_m,
            max_text=MAX_GUI_TEXT if slot is None or slot.bound else MAX_STRING,
        )

    def refuse(self, reason: str) -> Dropped:
        key = reason.split(":")[0].split(" (")[0]
        with self._lock:
            self.dropped[key] += 1
            count = self.dropped[key]
        if self.notes.due(key):
            LOGGER.warning("refused an incoming message: %s (%d refused so far)", reason, count)
        if self.on_drop is not None:
            self._report(self.on_drop, reason)
        slot = self._slot()
        if self.on_bound_drop is not None and slot is not None and slot.bound:
            self._report(self.on_bound_drop, slot.client_id, reason)
        return Dropped(reason=reason)

    def _report(self, callback: Callable[..., None], *args: Any) -> None:
        try:
            callback(*args)
        except Exception:
            self.notes.note("drop callback", "a firewall drop callback failed")


def _cookie(headers: Any, name: str) -> str:
    """The value of cookie ``name`` in a request's ``Cookie`` headers ("" if none or unreadable)."""
    for value in headers.get_all("Cookie")[:4]:
        if len(value) > 4096:
            continue
        jar: SimpleCookie = SimpleCookie()
        try:
            jar.load(value)
        except CookieError:
            continue
        if name in jar:
            return jar[name].value
    return ""

"""``Door``: who may open a connection to the port, checked before anything of theirs is read.

* Before a request is read (:meth:`Door.accepts`): new TCP connections per address
  (``shares.AcceptGate``, generous: a page load needs two); over it, the socket is reset.
* At a websocket handshake (:meth:`Door.process_request`): refused with 403 (never 500):
  another site's ``Origin``, a repeated ``Host``/``Origin``/``Upgrade`` header, a ``Host``
  carrying userinfo or a path, a name other than this machine's on a loopback-only port, a
  client that does not speak this server's viser version, a new tab (no rejoin token) over its
  address's rate of new tabs (a second ``AcceptGate``, strict: each tab costs the server about
  10 ms of work), and no slot left (``slots.Slots``: per address and in all, shared fairly,
  with room kept for tabs that present a session's rejoin token). A request for a file that
  cannot even be named gets 404; every other response passes ``page_filter``.
"""

from __future__ import annotations

import http
import threading
from collections import Counter
from collections.abc import Callable
from http.cookies import CookieError, SimpleCookie
from typing import Any
from urllib.parse import urlsplit

from websockets.datastructures import Headers
from websockets.http11 import Response

from study.server import viser_door
from study.server.firewall.notes import Notes
from study.server.firewall.port_config import FirewallConfig
from study.server.firewall.rules import LOOPBACK_NAMES
from study.server.firewall.shares import AcceptGate
from study.server.firewall.slots import Slots, close_slot
from study.server.forwarded import accepted_hosts, client_address, is_trusted

REPEATED_HEADERS = ("Host", "Origin", "Upgrade")
REJOIN_COOKIE = "study-rejoin"
"""The cookie a bound tab keeps its session's rejoin token in (sent with its next handshake)."""


def remote_host(connection: Any) -> str:
    """The peer address of a websocket connection ("unknown" if it has none)."""
    remote = getattr(connection, "remote_address", None)
    return str(remote[0]) if isinstance(remote, tuple) and remote else "unknown"


class Door:
    """The checks before and at a handshake on one port, and the connections they refused."""

    def __init__(
        self,
        config: FirewallConfig,
        *,
        slots: Slots,
        notes: Notes,
        clock: Callable[[], float],
    ) -> None:
        self.config = config
        self.slots = slots
        self.notes = notes
        self._clock = clock
        self.gate = (
            None
            if config.accept_per_s is None
            else AcceptGate(
                per_s=config.accept_per_s,
                burst=config.accept_burst,
                total_per_s=config.accept_total_per_s,
            )
        )
        self.tab_gate = (
            None
            if config.new_tabs_per_s is None
            else AcceptGate(
                per_s=config.new_tabs_per_s,
                burst=config.new_tabs_burst,
                total_per_s=config.new_tabs_total_per_s,
            )
        )
        self.rejoin_token: Callable[[str], str | None] = lambda _value: None
        """Set by the server: the session token a rejoin cookie's value proves, else ``None``."""
        self.page_filter: Callable[[Any, Any], Any] | None = None
        """Rewrites viser's HTTP responses, ``(request, response) -> response`` (the study
        server's page head: ``study.server.page_head``)."""
        self.refused_connections: Counter[str] = Counter()
        self._lock = threading.Lock()

    def client_host(self, connection: Any, headers: Any = None) -> str:
        """The address limits and logs use for ``connection`` (the one place that says): its
        peer's, or behind a trusted proxy the client's (``study.server.forwarded``)."""
        if headers is None:
            request = getattr(connection, "request", None)
            headers = getattr(request, "headers", None)
        trusted = self.config.trusted_proxies
        return client_address(remote_host(connection), headers, trusted=trusted)

    # -- before the request ------------------------------------------------------------------
    def accepts(self, peer: str) -> bool:
        """A new TCP connection from ``peer``: False to reset it before reading anything."""
        gate = self.gate
        if (
            gate is None
            or is_trusted(peer, self.config.trusted_proxies)
            or gate.allow(peer, self._clock())
        ):
            return True  # a trusted proxy carries every client: the door counts them by address
        self.notes.note("accept gate", f"reset new connections from {peer}: too many too fast")
        with self._lock:
            self.refused_connections["too many new connections from one address"] += 1
        return False

    # -- at the door -------------------------------------------------------------------------
    def process_request(self, inner: Callable[..., Any] | None) -> Callable[..., Any]:
        """Wrap viser's HTTP handler: origin and slot checks, and 404 for bad paths."""

        def handle(connection: Any, request: Any) -> Any:
            repeated = [h for h in REPEATED_HEADERS if len(request.headers.get_all(h)) > 1]
            if repeated:
                return self._forbid(f"a repeated {repeated[0]} header")
            if request.headers.get("Upgrade", "").lower() == "websocket":
                problem = self.problem(connection, request)
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

    def problem(self, connection: Any, request: Any) -> str | None:
        """Why the websocket handshake ``request`` is refused (``None``: it is let in, and
        holds a slot from now on)."""
        headers = request.headers
        problem = self._header_problem(connection, headers)
        if problem is not None:
            return problem
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
            close_slot(evict, 1013)
        return None

    def _header_problem(self, connection: Any, headers: Any) -> str | None:
        """What is wrong with a handshake's headers: its host, its origin, its version."""
        host = headers.get("Host", "")
        if any(ch in host for ch in "@/\\?#"):  # userinfo or a path: not a host name
            return "a malformed Host header"
        if self.config.loopback_only and urlsplit(f"//{host}").hostname not in LOOPBACK_NAMES:
            return "a name other than this machine's (DNS rebinding)"
        if self.config.check_origin:
            origin = headers.get("Origin")
            trusted = self.config.trusted_proxies
            hosts = accepted_hosts(remote_host(connection), headers, trusted=trusted)
            if origin is not None and urlsplit(origin).netloc.lower() not in hosts:
                return "another site's page (origin check)"
        offered = {
            p.strip() for v in headers.get_all("Sec-WebSocket-Protocol") for p in v.split(",")
        }
        if viser_door.SUBPROTOCOL not in offered:
            return "a client that does not speak this server's version"
        return None


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

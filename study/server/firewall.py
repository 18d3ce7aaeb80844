"""Inbound firewall for a viser server: what a browser may send, and how much.

viser decodes every websocket message a browser sends with ``Message.deserialize`` on the
server's event loop and dispatches it to whatever handler is registered for its type -- among
them ``ShareUrlRequest``, which opens a public tunnel. Two hooks put a :class:`Firewall` in
front of that:

* at the door, :func:`hardened_serve` (around the ``ViserServer`` constructor) gives the
  websocket server a message-size limit of ``max_bytes`` from the handshake on (a bigger
  message closes its connection before it is buffered), refuses a websocket whose ``Origin``
  is another site's (a page elsewhere in the browser cannot drive the study), refuses more than
  ``max_connections_per_address`` / ``max_connections`` open websockets (an address being,
  behind a trusted reverse proxy, the client's it forwards: ``trusted_proxies``,
  :mod:`study.server.forwarded`, which also gives the host names the origin check accepts),
  refuses a repeated ``Host``/``Origin``/``Upgrade`` header and a ``Host`` carrying userinfo
  or a path (403, never 500), and answers a request for a file it cannot even name (a 5,000-character path) with 404
  instead of 500;
* per frame, before viser sees it (:meth:`Firewall.screened_recv`): a text frame (viser speaks
  binary) closes its connection with 1003; and a server-wide budget of ``budget_per_s``
  messages a second (a token bucket shared by every connection, burst ``budget_burst``) drops
  the excess before it is decoded -- many sockets each under its own rate must not starve the
  control loop of the GIL. When the budget stays exhausted for ``evict_after_s`` seconds, the
  connections of the address that sent most in the last second are closed (one address per
  second; the connection caps bound how fast it can come back);
* per message, :func:`install` wraps the decoder once per process; for a server with a
  firewall each incoming message is checked *before* it becomes a message object:

  1. rate: at most ``rate_per_s`` messages a second per connection (burst ``burst``); a
     connection far over it, or with ``max_refused`` refused messages, is closed. The rate is
     counted when viser reads a message, not when it arrived (the kernel buffers it without a
     timestamp), so a backlog read at once after a stall of the event loop looks like a burst:
     a connection the server has not read from for ``t`` seconds may spend ``rate_per_s * t``
     (up to ``backlog_s`` seconds' worth) on top of its burst -- what an honest page could have
     queued meanwhile. Its long-run rate stays bounded, and the server-wide budget bounds load;
  2. size: at most ``max_bytes`` (a pose is about 150 bytes);
  3. type: only the types in ``allowed`` (an explicit allow-list) pass;
  4. values: every number finite and bounded (a pose within ``max_position_m`` of the origin,
     a unit-ish quaternion), strings and containers short, GUI updates carry only ``value``.

A refused message is replaced by a :class:`Dropped` message that no handler listens to, counted
under a fixed reason (never a name the client chose), and logged as a one-line summary (never
its payload) at most once per reason every ``log_every_s`` seconds. A connection closed for
what it sent (:class:`ConnectionFlood`) closes with a policy code and no traceback in the log.
Servers without a firewall pass untouched.
"""

from __future__ import annotations

import asyncio
import contextlib
import http
import logging
import math
import threading
import time
import weakref
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

import msgspec
import viser
import websockets.asyncio.server as ws_server
from viser import _messages as vm
from websockets.datastructures import Headers
from websockets.http11 import Response

from study.server.forwarded import Network, accepted_hosts, client_address

LOGGER = logging.getLogger("study.server.firewall")

PARTICIPANT_TYPES: frozenset[str] = frozenset(
    {
        "ViewerCameraMessage",
        "GuiUpdateMessage",
        "TransformControlsUpdateMessage",
        "TransformControlsDragStartMessage",
        "TransformControlsDragEndMessage",
        "LocalStorageGetItemResponseMessage",
    }
)
"""What the participant page needs to send: its camera, GUI values, the handle's pose, and the
join code it kept for a reload (the answer to the server's local-storage request)."""

SHARE_TYPES: frozenset[str] = frozenset({"ShareUrlRequest", "ShareUrlDisconnect"})

LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "::1"})
"""Host names a loopback-only server (the console) answers to: a page whose own name was made
to point at 127.0.0.1 (DNS rebinding) passes the origin check, but not this one."""

MAX_MESSAGE_BYTES = 16 * 1024
"""Largest message a participant's browser sends in normal use is well under 1 KiB."""

MAX_POSITION_M = 10.0
MAX_STRING = 64
"""Longest string a page sends: a join code, an answer, a key state, a node name."""


@dataclass(eq=False)
class Dropped(vm.Message, include_in_scene_serialization=False):
    """Stands in for a refused incoming message; nothing handles it."""

    reason: str


class RefusedMessage(ValueError):
    """An incoming message broke a rule; the text says which (never the payload)."""


class ConnectionFlood(ConnectionError):
    """A connection sent far more, or far worse, than a page does; it is closed with ``code``
    (1008 policy violation, or 1003 for data viser does not speak)."""

    def __init__(self, why: str, *, code: int = 1008) -> None:
        super().__init__(why)
        self.code = code


BUDGET = "over the server's message budget"
REPEATED_HEADERS = ("Host", "Origin", "Upgrade")


def _finite(value: Any, *, bound: float, what: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RefusedMessage(f"{what} is not a number")
    if not math.isfinite(value) or abs(value) > bound:
        raise RefusedMessage(f"{what} is not finite or beyond {bound:g}")


def _vector(value: Any, *, n: int, bound: float, what: str) -> None:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise RefusedMessage(f"{what} is not {n} numbers")
    for x in value:
        _finite(x, bound=bound, what=what)


def _string(value: Any, *, what: str, limit: int = MAX_STRING) -> None:
    if not isinstance(value, str) or len(value) > limit:
        raise RefusedMessage(f"{what} is not a string of at most {limit} characters")


def check_values(kind: str, body: dict[str, Any], *, max_position_m: float) -> None:
    """Raise :class:`RefusedMessage` unless ``body`` (a decoded message) is plausible."""
    if kind == "TransformControlsUpdateMessage":
        _string(body.get("name"), what="handle name")
        _string(body.get("owner", ""), what="handle owner")
        _vector(body.get("position"), n=3, bound=max_position_m, what="handle position")
        _vector(body.get("wxyz"), n=4, bound=2.0, what="handle orientation")
    elif kind in ("TransformControlsDragStartMessage", "TransformControlsDragEndMessage"):
        _string(body.get("name"), what="handle name")
        _string(body.get("owner", ""), what="handle owner")
    elif kind == "GuiUpdateMessage":
        _string(body.get("uuid"), what="GUI id", limit=64)
        updates = body.get("updates")
        if not isinstance(updates, dict) or set(updates) != {"value"}:
            raise RefusedMessage("GUI update changes something other than its value")
        value = updates["value"]
        if isinstance(value, str):
            _string(value, what="GUI value")
        elif not isinstance(value, bool):
            _finite(value, bound=1e9, what="GUI value")
    elif kind == "LocalStorageGetItemResponseMessage":
        _string(body.get("request_uuid"), what="storage request id", limit=64)
        for key in ("value", "error"):
            if body.get(key) is not None:
                _string(body.get(key), what=f"storage {key}", limit=64)
    elif kind == "ViewerCameraMessage":
        for key in ("wxyz", "position", "look_at", "up_direction"):
            n = 4 if key == "wxyz" else 3
            _vector(body.get(key), n=n, bound=1e4, what=f"camera {key}")
        for key in ("fov", "near", "far"):
            _finite(body.get(key), bound=1e6, what=f"camera {key}")
        for key in ("image_height", "image_width"):
            _finite(body.get(key), bound=1e5, what=f"camera {key}")


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
        trusted_proxies: tuple[Network, ...] = (),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.allowed = None if allowed is None else frozenset(allowed) - SHARE_TYPES
        if allow_share and self.allowed is not None:
            self.allowed |= SHARE_TYPES
        self.allow_share = allow_share
        self.max_bytes = max_bytes
        self.max_position_m = max_position_m
        self.log_every_s = log_every_s
        self.on_drop = on_drop
        self.rate_per_s = rate_per_s
        self.burst = burst
        self.max_refused = max_refused
        self.max_connections = max_connections
        self.max_connections_per_address = max_connections_per_address
        self.check_origin = check_origin
        self.loopback_only = loopback_only
        self.backlog_s = backlog_s
        self.budget_per_s = budget_per_s
        self.budget_burst = budget_burst
        self.evict_after_s = evict_after_s
        self.trusted_proxies = trusted_proxies
        """Peers whose forwarded client address counts (``study.server.forwarded``)."""
        self._clock = clock  # of the rate limits (a test's own clock)
        self.passed = 0
        self.dropped: Counter[str] = Counter()
        self.closed_connections = 0
        self.refused_connections: Counter[str] = Counter()
        self._logged: dict[str, float] = {}
        self._lock = threading.Lock()
        self._server: viser.ViserServer | None = None
        # per connection (its message-reading task): [tokens, last time, refused]
        self._buckets: weakref.WeakKeyDictionary[asyncio.Task[Any], list[float]] = (
            weakref.WeakKeyDictionary()
        )
        # the server-wide budget (touched only on the server's event loop)
        self._budget = budget_burst
        self._budget_t = self._clock()
        self._window_t = self._budget_t
        self._window_sent: Counter[str] = Counter()
        self._window_dropped = 0
        self._over_windows = 0
        self._evict: str | None = None

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
        self._note("connection refused", problem)
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
            hosts = accepted_hosts(
                _remote_host(connection), request.headers, trusted=self.trusted_proxies
            )
            if origin is not None and urlsplit(origin).netloc.lower() not in hosts:
                return "another site's page (origin check)"
        server = self._server
        live = dict(server._websock_server._live_connections) if server is not None else {}
        if len(live) >= self.max_connections:
            return f"too many connections ({len(live)})"
        address = self.client_host(connection, request.headers)
        same = sum(1 for c in live.values() if self.client_host(c) == address)
        if same >= self.max_connections_per_address:
            return f"too many connections from one address ({same})"
        return None

    def client_host(self, connection: Any, headers: Any = None) -> str:
        """The address limits and logs use for ``connection``: its peer's, or behind a trusted
        proxy the client's (``study.server.forwarded``)."""
        if headers is None:
            request = getattr(connection, "request", None)
            headers = getattr(request, "headers", None)
        return client_address(_remote_host(connection), headers, trusted=self.trusted_proxies)

    # -- per message -----------------------------------------------------------------------------
    def admit(self) -> None:
        """Count one message of the current connection; raise :class:`ConnectionFlood` to
        close a connection far over its rate or with too many refused messages."""
        task = asyncio.current_task()
        if task is None:
            return
        now = self._clock()
        bucket = self._buckets.get(task)
        if bucket is None:
            bucket = self._buckets[task] = [self.burst, now, 0.0]
        elapsed = now - bucket[1]
        # credit for the time this connection went unread (a backlog), never clipped down
        cap = self.burst + self.rate_per_s * min(elapsed, self.backlog_s)
        bucket[0] = min(max(cap, bucket[0]), bucket[0] + elapsed * self.rate_per_s)
        bucket[2] = max(0.0, bucket[2] - elapsed)  # refusals are forgiven at one a second
        bucket[1] = now
        bucket[0] -= 1.0
        if bucket[0] < -self.burst:  # twice the burst over the rate: not a page
            self._closing(f"more than {self.rate_per_s:g} messages a second")

    def _count_refusal(self) -> None:
        task = asyncio.current_task()
        bucket = self._buckets.get(task) if task is not None else None
        if bucket is not None:
            bucket[2] += 1
            if bucket[2] > self.max_refused:
                self._closing(f"more than {self.max_refused} refused messages")

    def _closing(self, why: str, *, code: int = 1008) -> None:
        with self._lock:
            self.closed_connections += 1
        self._note("connection closed", f"closed a connection that sent {why}")
        raise ConnectionFlood(why, code=code)

    # -- per frame, before viser ---------------------------------------------------------------
    def screened_recv(self, connection: Any) -> Callable[..., Any]:
        """``connection.recv`` behind the text-frame rule and the server-wide budget."""
        recv = connection.recv
        address = self.client_host(connection)

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
        """Take one message from the server-wide bucket; False (counted) when it is empty."""
        if self.budget_per_s is None:
            return True
        now = self._clock()
        if now - self._window_t >= 1.0:
            self._next_window(now)
        if address == self._evict:
            self._closing("its share of a flood over the server's message budget")
        self._window_sent[address] += 1
        elapsed, self._budget_t = now - self._budget_t, now
        self._budget = min(self.budget_burst, self._budget + elapsed * self.budget_per_s)
        if self._budget >= 1.0:
            self._budget -= 1.0
            return True
        self._window_dropped += 1
        self.refuse(f"{BUDGET} ({self.budget_per_s:g} a second)")
        return False

    def _next_window(self, now: float) -> None:
        """Close out a one-second window: after ``evict_after_s`` windows in a row with
        drops, the address that sent most in the last one is closed on its next message."""
        self._over_windows = self._over_windows + 1 if self._window_dropped else 0
        self._evict = None
        if self._over_windows >= self.evict_after_s and self._window_sent:
            self._evict = self._window_sent.most_common(1)[0][0]
            self._over_windows = 0
        self._window_sent.clear()
        self._window_dropped = 0
        self._window_t = now

    def screen(self, raw: bytes) -> str | None:
        """``None`` when ``raw`` may be decoded, else the reason it is refused."""
        if len(raw) > self.max_bytes:
            return f"message of {len(raw)} bytes (limit {self.max_bytes})"
        try:
            body = msgspec.msgpack.decode(raw)
        except Exception:  # not msgpack, or nested too deep to decode
            return "not a viser message"
        if not isinstance(body, dict) or not isinstance(body.get("type"), str):
            return "not a viser message"
        kind = body["type"]
        if kind in SHARE_TYPES and not self.allow_share:
            return f"{kind} (share links are off; start the server with --share to allow them)"
        if self.allowed is not None and kind not in self.allowed:
            known = kind in vm.Message._subclass_from_type_string()
            return f"{kind if known else 'an unknown type'} is not accepted here"
        if self.allowed is None:
            return None  # the console: every type, no value rules (reasons may be long)
        try:
            check_values(kind, body, max_position_m=self.max_position_m)
        except RefusedMessage as exc:
            return f"{kind}: {exc}"
        except Exception:  # a structure too odd to inspect (e.g. nested too deep)
            return f"{kind}: not inspectable"
        return None

    def _note(self, key: str, text: str) -> None:
        """Log ``text`` at most once per ``key`` every ``log_every_s`` seconds."""
        now = time.monotonic()
        with self._lock:
            last = self._logged.get(key)
            if last is not None and now - last < self.log_every_s:
                return
            self._logged[key] = now
        LOGGER.warning("%s", text.encode("unicode_escape").decode("ascii")[:300])

    def refuse(self, reason: str) -> Dropped:
        key = reason.split(":")[0].split(" (")[0]
        now = time.monotonic()
        with self._lock:
            self.dropped[key] += 1
            count = self.dropped[key]
            last = self._logged.get(key)
            log = last is None or now - last >= self.log_every_s
            if log:
                self._logged[key] = now
        if log:
            LOGGER.warning("refused an incoming message: %s (%d refused so far)", reason, count)
        if self.on_drop is not None:
            try:
                self.on_drop(reason)
            except Exception:
                LOGGER.exception("firewall on_drop callback failed")
        return Dropped(reason=reason)


class _OpenLinesOnceAMinute(logging.Filter):
    """websockets logs "connection open" (INFO) for every socket: a flood of sockets would be a
    flood of lines. Let one through a minute."""

    def __init__(self, every_s: float = 60.0) -> None:
        super().__init__()
        self.every_s = every_s
        self._last = -math.inf

    def filter(self, record: logging.LogRecord) -> bool:
        if record.msg != "connection open":
            return True
        now = time.monotonic()
        if now - self._last < self.every_s:
            return False
        self._last = now
        return True


_OPEN_LINES = _OpenLinesOnceAMinute()
_FIREWALLS: dict[int, Firewall] = {}
_INSTALL_LOCK = threading.Lock()
_ORIGINAL = vm.Message.deserialize.__func__  # type: ignore[attr-defined]


def _guarded_deserialize(cls: type[vm.Message], message: bytes) -> vm.Message:
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        return _ORIGINAL(cls, message)
    firewall = _FIREWALLS.get(id(loop))
    if firewall is None:
        return _ORIGINAL(cls, message)
    firewall.admit()
    reason = firewall.screen(message)
    if reason is not None:
        firewall._count_refusal()
        return firewall.refuse(reason)
    try:
        decoded = _ORIGINAL(cls, message)
    except Exception as exc:  # a field of the wrong shape for its type
        return firewall.refuse(f"undecodable message ({type(exc).__name__})")
    firewall.passed += 1
    return decoded


def install(server: viser.ViserServer, firewall: Firewall) -> Firewall:
    """Screen every message ``server`` receives from now on with ``firewall``."""
    loop = server._websock_server._background_event_loop
    if loop is None:  # pragma: no cover - viser starts its loop in the constructor
        raise RuntimeError("the viser server has no event loop yet; install after it starts")
    with _INSTALL_LOCK:
        if getattr(vm.Message.deserialize, "__func__", None) is not _guarded_deserialize:
            vm.Message.deserialize = classmethod(_guarded_deserialize)  # type: ignore[method-assign,assignment]
        _FIREWALLS[id(loop)] = firewall
    firewall._server = server
    return firewall


@contextlib.contextmanager
def hardened_serve(firewall: Firewall) -> Iterator[None]:
    """Build a ``ViserServer`` inside this block: its websocket server gets ``firewall``'s
    size limit and door checks (viser starts serving before its constructor returns)."""
    original = ws_server.serve

    def serve(handler: Any, *args: Any, **kwargs: Any) -> Any:
        async def guarded(connection: Any) -> None:
            connection.recv = firewall.screened_recv(connection)
            try:
                await handler(connection)
            except ConnectionFlood as exc:  # closed on purpose: no "handler failed" traceback
                with contextlib.suppress(Exception):
                    await connection.close(exc.code, "refused")

        kwargs["max_size"] = firewall.max_bytes
        kwargs["process_request"] = firewall.process_request(kwargs.get("process_request"))
        return original(guarded, *args, **kwargs)

    with _INSTALL_LOCK:
        ws_server.serve = serve  # type: ignore[assignment,misc]
        logging.getLogger("websockets.server").addFilter(_OPEN_LINES)  # once: filters are a set
    try:
        yield
    finally:
        with _INSTALL_LOCK:
            ws_server.serve = original  # type: ignore[misc]


def _remote_host(connection: Any) -> str:
    remote = getattr(connection, "remote_address", None)
    return str(remote[0]) if isinstance(remote, tuple) and remote else "unknown"


def uninstall(server: viser.ViserServer) -> None:
    loop = server._websock_server._background_event_loop
    with _INSTALL_LOCK:
        _FIREWALLS.pop(id(loop), None)

"""Inbound firewall for a viser server: what a browser may send, and how much.

viser decodes every websocket message a browser sends with ``Message.deserialize`` on the
server's event loop and dispatches it to whatever handler is registered for its type -- among
them ``ShareUrlRequest``, which opens a public tunnel. :func:`install` wraps that decoder once
per process; for a server with a :class:`Firewall`, each incoming message is checked *before*
it is decoded into a message object:

1. size: at most ``max_bytes`` (a pose is about 150 bytes); the websocket connection's own
   limit is lowered to the same figure at connect (:meth:`Firewall.limit_connection`), so a
   huge message closes that connection instead of being buffered;
2. type: only the types in ``allowed`` (an explicit allow-list) pass;
3. values: every number finite and bounded (a pose within ``max_position_m`` of the origin, a
   unit-ish quaternion), strings and containers short, GUI updates carry only ``value``.

A refused message is replaced by a :class:`Dropped` message that no handler listens to, counted
per reason, and logged as a one-line summary (never its payload) at most once per reason every
``log_every_s`` seconds. Servers without a firewall pass untouched.
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import msgspec
import viser
from viser import _messages as vm

LOGGER = logging.getLogger("app.ui.firewall")

PARTICIPANT_TYPES: frozenset[str] = frozenset(
    {
        "ViewerCameraMessage",
        "GuiUpdateMessage",
        "TransformControlsUpdateMessage",
        "TransformControlsDragStartMessage",
        "TransformControlsDragEndMessage",
    }
)
"""What the participant page needs to send: its camera, GUI values and the handle's pose."""

SHARE_TYPES: frozenset[str] = frozenset({"ShareUrlRequest", "ShareUrlDisconnect"})

MAX_MESSAGE_BYTES = 16 * 1024
"""Largest message a participant's browser sends in normal use is well under 1 KiB."""

MAX_POSITION_M = 10.0
MAX_STRING = 256


@dataclass(eq=False)
class Dropped(vm.Message, include_in_scene_serialization=False):
    """Stands in for a refused incoming message; nothing handles it."""

    reason: str


class RefusedMessage(ValueError):
    """An incoming message broke a rule; the text says which (never the payload)."""


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
    ) -> None:
        self.allowed = None if allowed is None else frozenset(allowed) - SHARE_TYPES
        if allow_share and self.allowed is not None:
            self.allowed |= SHARE_TYPES
        self.allow_share = allow_share
        self.max_bytes = max_bytes
        self.max_position_m = max_position_m
        self.log_every_s = log_every_s
        self.on_drop = on_drop
        self.passed = 0
        self.dropped: Counter[str] = Counter()
        self._logged: dict[str, float] = {}
        self._lock = threading.Lock()

    def limit_connection(self, server: viser.ViserServer, client_id: int) -> None:
        """Lower the websocket's message-size limit for ``client_id`` to ``max_bytes``."""
        connection = server._websock_server._live_connections.get(client_id)
        protocol = getattr(connection, "protocol", None)
        if protocol is not None and hasattr(protocol, "max_message_size"):
            protocol.max_message_size = self.max_bytes

    def screen(self, raw: bytes) -> str | None:
        """``None`` when ``raw`` may be decoded, else the reason it is refused."""
        if len(raw) > self.max_bytes:
            return f"message of {len(raw)} bytes (limit {self.max_bytes})"
        try:
            body = msgspec.msgpack.decode(raw)
        except (msgspec.DecodeError, ValueError, TypeError):
            return "not a viser message"
        if not isinstance(body, dict) or not isinstance(body.get("type"), str):
            return "not a viser message"
        kind = body["type"][:60]
        if kind in SHARE_TYPES and not self.allow_share:
            return f"{kind} (share links are off; start the server with --share to allow them)"
        if self.allowed is not None and kind not in self.allowed:
            return f"{kind} is not accepted here"
        try:
            check_values(kind, body, max_position_m=self.max_position_m)
        except RefusedMessage as exc:
            return f"{kind}: {exc}"
        return None

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
    reason = firewall.screen(message)
    if reason is not None:
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
    return firewall


def uninstall(server: viser.ViserServer) -> None:
    loop = server._websock_server._background_event_loop
    with _INSTALL_LOCK:
        _FIREWALLS.pop(id(loop), None)

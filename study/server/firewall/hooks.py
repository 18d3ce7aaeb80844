"""Where a :class:`~study.server.firewall.Firewall` hooks into viser and websockets.

* :func:`hardened_serve` (around the ``ViserServer`` constructor, which starts serving before
  it returns) gives the websocket server the firewall's size limit, its accept gate (a socket
  refused there is reset before its request is read), its door checks, no ``Server`` header
  (no version strings), and puts :meth:`Firewall.screened_recv` in front of every
  connection's reads;
* :func:`install` wraps viser's message decoder once per process: for a server with a firewall
  each incoming message is admitted and screened *before* it becomes a message object (a
  refused one becomes a :class:`~study.server.firewall.rules.Dropped` that nothing handles).
  Servers without a firewall pass untouched.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import viser
import websockets.asyncio.server as ws_server
from viser import _messages as vm
from websockets.asyncio.server import ServerConnection

from study.server.firewall.notes import OncePerMinute
from study.server.firewall.rules import ConnectionFlood

if TYPE_CHECKING:
    from study.server.firewall.port import Firewall

_WEBSOCKETS_LINES = OncePerMinute()
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
        firewall.count_refusal()
        return firewall.refuse(reason)
    try:
        decoded = _ORIGINAL(cls, message)
    except Exception as exc:  # a field of the wrong shape for its type
        return firewall.refuse(f"undecodable message ({type(exc).__name__})")
    firewall.admitted()
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
    firewall.attach(server)
    return firewall


def uninstall(server: viser.ViserServer) -> None:
    loop = server._websock_server._background_event_loop
    with _INSTALL_LOCK:
        firewall = _FIREWALLS.pop(id(loop), None)
    if firewall is not None:
        firewall.detach()


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
        kwargs["server_header"] = None
        kwargs["create_connection"] = gated_connection(firewall)
        return original(guarded, *args, **kwargs)

    with _INSTALL_LOCK:
        ws_server.serve = serve  # type: ignore[assignment,misc]
        logging.getLogger("websockets.server").addFilter(_WEBSOCKETS_LINES)  # a set: once
    try:
        yield
    finally:
        with _INSTALL_LOCK:
            ws_server.serve = original  # type: ignore[misc]


def gated_connection(firewall: Firewall) -> type[ServerConnection]:
    """A websockets connection class that asks ``firewall.accepts(peer)`` before anything is
    read (a refused socket is reset; nothing else runs for it) and frees its slot when gone."""

    class GatedConnection(ServerConnection):
        refused = False

        def connection_made(self, transport: asyncio.BaseTransport) -> None:
            peer = transport.get_extra_info("peername")
            address = str(peer[0]) if isinstance(peer, tuple) and peer else "unknown"
            if not firewall.accepts(address):
                self.refused = True
                transport.abort()
                return
            super().connection_made(transport)

        def data_received(self, data: bytes) -> None:
            if not self.refused:
                super().data_received(data)

        def eof_received(self) -> None:
            if not self.refused:
                super().eof_received()

        def connection_lost(self, exc: Exception | None) -> None:
            if self.refused:
                return
            firewall.connection_lost(self)
            super().connection_lost(exc)

    return GatedConnection


def remote_host(connection: Any) -> str:
    """The peer address of a websocket connection ("unknown" if it has none)."""
    remote = getattr(connection, "remote_address", None)
    return str(remote[0]) if isinstance(remote, tuple) and remote else "unknown"

"""Where a :class:`~study.server.firewall.Firewall` stands in front of a viser server, through
the hooks of :mod:`study.server.viser_door`.

* :func:`start_server` builds and starts a ``ViserServer`` whose websocket server has the
  firewall's size limit, its accept gate on the listening socket (a connection refused there
  is reset as it is accepted, :mod:`study.server.firewall.listener`), its door checks, no ``Server`` header (no version strings), and
  :meth:`Firewall.screened_recv` in front of every connection's reads;
* :func:`install` screens every message the server receives with
  :meth:`Firewall.screened_decode` *before* it becomes a message object (a refused one becomes
  a :class:`~study.server.firewall.rules.Dropped` that nothing handles). Servers without a
  firewall pass untouched.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from typing import TYPE_CHECKING, Any

import viser
from websockets.asyncio.server import ServerConnection
from websockets.frames import Frame, Opcode

from study.server import viser_door
from study.server.firewall.limits import FrameBudget
from study.server.firewall.listener import gate_listener
from study.server.firewall.notes import OncePerMinute
from study.server.firewall.rules import ConnectionFlood

if TYPE_CHECKING:
    from study.server.firewall.port import Firewall

_WEBSOCKETS_LINES = OncePerMinute()
_INSTALLED: dict[int, Firewall] = {}
_LOCK = threading.Lock()


def install(server: viser.ViserServer, firewall: Firewall) -> Firewall:
    """Screen every message ``server`` receives from now on with ``firewall``."""
    with _LOCK:
        viser_door.screen_incoming(server, firewall.screened_decode)
        _INSTALLED[id(server)] = firewall
    firewall.attach(server)
    return firewall


def uninstall(server: viser.ViserServer) -> None:
    with _LOCK:
        viser_door.unscreen_incoming(server)
        firewall = _INSTALLED.pop(id(server), None)
    if firewall is not None:
        firewall.detach()


def start_server(firewall: Firewall, *, host: str, port: int, verbose: bool) -> viser.ViserServer:
    """A started ``ViserServer`` whose websocket server has ``firewall``'s size limit and door
    checks (viser starts serving before its constructor returns)."""
    logging.getLogger("websockets.server").addFilter(_WEBSOCKETS_LINES)  # a set: once

    def adapt(handler: Any, kwargs: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
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
        gate_listener(asyncio.get_running_loop(), firewall.accepts)  # viser serves in its loop
        return guarded, kwargs

    return viser_door.start_server(host=host, port=port, verbose=verbose, adapt_serve=adapt)


def gated_connection(firewall: Firewall) -> type[ServerConnection]:
    """A websockets connection class that closes a connection that breaks its
    ``FrameBudget`` (fragments of one message, pings) before the library keeps or answers more
    of it, and frees its slot when gone. (``firewall.accepts`` was asked before: the listening
    socket's gate, :mod:`study.server.firewall.listener`.)"""
    return type("GatedConnection", (GatedConnection,), {"firewall": firewall})


class GatedConnection(ServerConnection):
    """A connection behind ``firewall`` (a subclass per firewall: ``gated_connection``)."""

    firewall: Firewall
    failed = False
    budget: FrameBudget | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        config = self.firewall.config
        self.budget = FrameBudget(
            max_fragments=config.max_fragments,
            pings_per_s=config.pings_per_s,
            ping_burst=config.ping_burst,
            last=time.monotonic(),
        )
        super().connection_made(transport)

    def process_event(self, event: Frame) -> None:  # type: ignore[override]
        if self.failed:
            return  # closing: nothing more is kept or handled
        why = self._over_budget(event)
        if why is None:
            super().process_event(event)
            return
        self.failed = True
        self.firewall.frames_refused(why)
        self.protocol.fail(1009 if "frames" in why else 1008, "refused")
        self.send_data()

    def _over_budget(self, event: Frame) -> str | None:
        budget = self.budget
        if budget is None or not isinstance(event, Frame):
            return None  # the handshake's events
        if event.opcode in (Opcode.TEXT, Opcode.BINARY, Opcode.CONT):
            return budget.data(fin=event.fin)
        if event.opcode is Opcode.PING:
            return budget.ping(time.monotonic())
        return None

    def connection_lost(self, exc: Exception | None) -> None:
        self.firewall.connection_lost(self)
        super().connection_lost(exc)

"""The accept gate on the listening socket: a connection refused by its address's rate is reset
as it is accepted, before asyncio builds anything for it.

asyncio's selector loop accepts a ready connection in ``_accept_connection(factory, sock, ...)``
and, for each one, starts a task, builds the protocol (websockets' connection and its parser),
a transport and a selector registration; a connection refused only once it is made
(``connection_made``) has cost all of that. :func:`gate_listener` hands that method a view of
the listening socket whose ``accept()`` asks ``admit(address)`` first and resets (``SO_LINGER``
0, so an RST and no ``TIME_WAIT``) every connection refused, returning only admitted ones: a
flood of bare connects from one address then costs the server an ``accept`` and a ``close``
each (``benchmarks/README.md``, "Bare connects at the listening socket").

The one private reach: ``BaseSelectorEventLoop._accept_connection`` (CPython 3.11-3.13), set
on the loop instance; ``tests/test_firewall_listener.py`` fails if it moves.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct
from collections.abc import Callable
from typing import Any

REFUSED_PER_CALL = 64
"""Refused connections reset in one ``accept()`` before the loop is given back to its other
callbacks (a flood never keeps the event loop in the accept call)."""

_LINGER_RESET = struct.pack("ii", 1, 0)


class ListenerGateError(RuntimeError):
    """The event loop has no accept method to gate (not asyncio's selector loop): run the
    server on the standard asyncio loop."""


class GatedListener:
    """A listening socket as asyncio's accept loop sees it: ``accept()`` returns the next
    connection ``admit`` lets in and resets the others (module docstring)."""

    __slots__ = ("_admit", "_sock")

    def __init__(self, sock: socket.socket, admit: Callable[[str], bool]) -> None:
        self._sock = sock
        self._admit = admit

    def accept(self) -> tuple[socket.socket, Any]:
        for _ in range(REFUSED_PER_CALL):
            conn, address = self._sock.accept()  # BlockingIOError: none left, the loop returns
            host = str(address[0]) if isinstance(address, tuple) and address else "unknown"
            if self._admit(host):
                return conn, address
            reset(conn)
        raise BlockingIOError("refused connections reset; the rest on the next loop pass")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sock, name)


def reset(conn: socket.socket) -> None:
    """Close ``conn`` with an RST: nothing of it is read and the kernel keeps no state."""
    with contextlib.suppress(OSError):
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, _LINGER_RESET)
    conn.close()


def gate_listener(loop: asyncio.AbstractEventLoop, admit: Callable[[str], bool]) -> None:
    """Gate every listening socket ``loop`` starts serving from now on with ``admit(address)``
    (a new TCP connection refused is reset before anything is built for it)."""
    original = getattr(loop, "_accept_connection", None)
    if original is None:
        raise ListenerGateError(f"{type(loop).__name__} has no _accept_connection to gate")

    def accept_connection(factory: Any, sock: Any, *args: Any, **kwargs: Any) -> Any:
        if not isinstance(sock, GatedListener):  # a retry after EMFILE passes it back
            sock = GatedListener(sock, admit)
        return original(factory, sock, *args, **kwargs)

    loop._accept_connection = accept_connection  # type: ignore[attr-defined]

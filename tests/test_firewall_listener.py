"""The accept gate on the listening socket (``study.server.firewall.listener``): a connection
its address may not open is reset as it is accepted, before asyncio builds anything for it."""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from study.server.firewall.listener import REFUSED_PER_CALL, gate_listener


class Served:
    """An asyncio echo-once server on 127.0.0.1 whose loop runs in a thread, gated by
    ``admit``; ``made`` counts the protocols asyncio built (connections it did work for)."""

    def __init__(self, admit: Callable[[str], bool]) -> None:
        self.made = 0
        self.loop = asyncio.new_event_loop()
        gate_listener(self.loop, admit)
        served = self

        class Echo(asyncio.Protocol):
            def connection_made(self, transport: asyncio.BaseTransport) -> None:
                served.made += 1
                self.transport = transport

            def data_received(self, data: bytes) -> None:
                self.transport.write(data)  # type: ignore[attr-defined]

        # the loop runs in its own thread from the start: this thread may already have one
        # running (Playwright's, in a worker that ran the browser tests)
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.server = asyncio.run_coroutine_threadsafe(
            self.loop.create_server(Echo, "127.0.0.1", 0, backlog=1024), self.loop
        ).result(timeout=10)
        self.port = self.server.sockets[0].getsockname()[1]

    def close(self) -> None:
        async def shut() -> None:
            self.server.close()
            await self.server.wait_closed()

        asyncio.run_coroutine_threadsafe(shut(), self.loop).result(timeout=10)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()


Make = Callable[[Callable[[str], bool]], Served]


@pytest.fixture
def served() -> Iterator[Make]:
    made: list[Served] = []

    def make(admit: Callable[[str], bool]) -> Served:
        made.append(Served(admit))
        return made[-1]

    yield make
    for s in made:
        s.close()


def _connect(port: int, source: str) -> socket.socket:
    sock = socket.socket()
    sock.settimeout(5)
    sock.bind((source, 0))
    sock.connect(("127.0.0.1", port))
    return sock


def _connect_refused(port: int, source: str) -> socket.socket | None:
    """Connect from an address the gate refuses; ``None`` if the reset came back before
    ``connect`` returned (a loaded machine may run the server's accept first)."""
    try:
        return _connect(port, source)
    except ConnectionResetError:
        return None


def _answered(sock: socket.socket | None) -> bool:
    """Whether the server answered what ``sock`` sent (a reset or a close is no answer)."""
    if sock is None:
        return False
    try:
        sock.sendall(b"hello")
        return sock.recv(16) == b"hello"
    except ConnectionResetError:
        return False


def test_a_refused_address_is_reset_and_nothing_is_built_for_it(served: Make) -> None:
    s = served(lambda host: host != "127.0.0.2")
    refused = _connect_refused(s.port, "127.0.0.2")
    assert not _answered(refused)
    if refused is not None:
        refused.close()
    honest = _connect(s.port, "127.0.0.1")
    assert _answered(honest)
    honest.close()
    assert s.made == 1  # only the admitted connection cost a protocol


def test_a_flood_of_refused_connects_never_keeps_an_admitted_one_waiting(served: Make) -> None:
    s = served(lambda host: host != "127.0.0.2")
    s.loop.call_soon_threadsafe(time.sleep, 0.5)  # the loop busy: connections queue up
    flood = [_connect_refused(s.port, "127.0.0.2") for _ in range(3 * REFUSED_PER_CALL)]
    honest = _connect(s.port, "127.0.0.1")  # in the kernel's queue behind them all
    start = time.monotonic()
    assert _answered(honest)
    assert time.monotonic() - start < 2.0
    assert s.made == 1
    assert not any(_answered(sock) for sock in flood[:8])
    for sock in flood:
        if sock is not None:
            sock.close()
    honest.close()


def test_the_gate_needs_asyncios_selector_loop() -> None:
    loop = asyncio.new_event_loop()
    try:
        assert callable(getattr(loop, "_accept_connection", None)), (
            "asyncio moved its accept method: study.server.firewall.listener must follow"
        )
    finally:
        loop.close()

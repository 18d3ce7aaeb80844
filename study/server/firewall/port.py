"""``Firewall``: the rules for one viser server's port, and what they refused.

* Before a request is read and at the handshake: the :class:`~study.server.firewall.door.Door`
  (accept gate, header, origin and version checks, new tabs, slots).
* Per frame, before viser (``screened_recv``): a text frame closes its connection with 1003;
  an unbound connection waits for its address's share (``shares.FairShares``; a message counts
  once per KiB begun); a bound tab waits only past ``bound_bytes_per_s`` (``shares.ByteBudget``,
  far above what a page sends).
* Per message (``screened_decode``, viser's decoder through ``study.server.viser_door``): the
  per-connection :class:`~study.server.firewall.limits.ConnectionRate`, then ``rules.screen``;
  GUI text values up to ``rules.MAX_GUI_TEXT`` characters from a bound tab (a free-text
  answer), up to ``rules.MAX_STRING`` from any other (a join code, a link's IDs).
* Every second, slots that never sent a message, or sat idle on the join screen too long, are
  closed.

The limits are one :class:`~study.server.firewall.port_config.FirewallConfig`. A refused
message is counted under its reason (a message type viser knows, or "an unknown type": never a
name the client chose) and logged as a one-line summary at most once per kind of reason every
``log_every_s`` seconds (:func:`~study.server.firewall.rules.reason_kind`: sizes and type names
left out, so a client cannot make a line per size or per type); one refused from a
bound tab is reported to ``on_bound_drop`` (the session records it). A connection closed for
what it sent (:class:`ConnectionFlood`) closes with a policy code and no traceback.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time
import weakref
from collections import Counter
from collections.abc import Callable
from typing import Any

import viser

from study.server import viser_door
from study.server.firewall import rules
from study.server.firewall.door import Door
from study.server.firewall.limits import ConnectionRate
from study.server.firewall.notes import LOGGER, Notes
from study.server.firewall.port_config import FirewallConfig
from study.server.firewall.rules import (
    MAX_GUI_TEXT,
    MAX_STRING,
    SHARE_TYPES,
    ConnectionFlood,
    Dropped,
)
from study.server.firewall.shares import ByteBudget, FairShares
from study.server.firewall.slots import Slot, Slots, close_slot

SWEEP_EVERY_S = 1.0


LOST_POLL_S = 0.25
"""How often a held frame's connection is looked at in the kernel (:func:`_peer_gone`)."""
_TCP_ESTABLISHED = 1


def _peer_gone(connection: Any) -> bool:
    """Whether the kernel no longer holds ``connection``'s TCP connection as established (the
    peer reset it, or closed its side without a websocket close). While a frame is held the
    connection's reads are paused, so asyncio never hears of the loss: a flooder's sockets,
    reset mid-hold, kept their slots and had their queued frames handed to viser at the share's
    pace for 30 s after the flooder was gone. ``False`` where the state cannot be read (not
    TCP, or not Linux)."""
    transport = getattr(connection, "transport", None)
    sock = None if transport is None else transport.get_extra_info("socket")
    if sock is None or not hasattr(socket, "TCP_INFO"):
        return False
    if sock.family not in (socket.AF_INET, socket.AF_INET6):
        return False
    try:
        state = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 1)
    except OSError:  # its descriptor is closed: the transport reports the loss itself
        return False
    return state[0] != _TCP_ESTABLISHED


async def _unless_lost(connection: Any, seconds: float) -> None:
    """Wait ``seconds``, unless ``connection`` is lost first: then raise its
    ``ConnectionClosed``, so a frame held back for its share is never handed to viser after its
    connection is gone (websockets' ``recv`` still returns frames queued before), and the
    connection's handler ends with it instead of when the wait would have. The kernel's view
    of the connection is looked at every ``LOST_POLL_S`` (:func:`_peer_gone`); a lost one is
    aborted, which is what ends the wait."""
    lost = getattr(connection, "connection_lost_waiter", None)  # a websockets connection's
    if lost is None:
        await asyncio.sleep(seconds)
        return
    end = asyncio.get_running_loop().time() + seconds
    while not lost.done():
        left = end - asyncio.get_running_loop().time()
        if left <= 0.0:
            break
        await asyncio.wait((lost,), timeout=min(left, LOST_POLL_S))  # never cancels ``lost``
        if not lost.done() and _peer_gone(connection):
            connection.transport.abort()  # connection_lost follows on the next turn
            await asyncio.wait((lost,), timeout=1.0)
    if lost.done():
        raise connection.protocol.close_exc


class Firewall:
    """The rules for one viser server's incoming connections and messages, and what they
    refused. ``config``: its limits (the participant port's by default); ``on_drop`` and
    ``on_bound_drop``: called with each refused message's reason (``on_bound_drop`` with the
    tab's client id too, for a tab that holds a session); ``clock``: of the rate limits and
    slots (a test's own clock)."""

    def __init__(
        self,
        config: FirewallConfig | None = None,
        *,
        on_drop: Callable[[str], None] | None = None,
        on_bound_drop: Callable[[int, str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config = config or FirewallConfig()
        allowed = config.allowed
        self.allowed = None if allowed is None else frozenset(allowed) - SHARE_TYPES
        if config.allow_share and self.allowed is not None:
            self.allowed |= SHARE_TYPES
        self.on_drop = on_drop
        self.on_bound_drop = on_bound_drop
        self._clock = clock
        self.notes = Notes(every_s=config.log_every_s)
        self.slots = Slots(
            max_total=config.max_connections,
            max_per_address=config.max_connections_per_address,
            greet_timeout_s=config.greet_timeout_s,
            idle_timeout_s=config.idle_timeout_s,
        )
        self.door = Door(config, slots=self.slots, notes=self.notes, clock=clock)
        self.shares = None if config.shares_per_s is None else FairShares(per_s=config.shares_per_s)
        self.slowed = 0
        """Reads of a bound tab that waited for its byte budget."""
        self.passed = 0
        self.dropped: Counter[str] = Counter()
        self.closed_connections = 0
        self._lock = threading.Lock()
        self._server: viser.ViserServer | None = None
        self._sweeper: asyncio.Task[None] | None = None
        # the slot of each connection's message-reading task
        self._task_slots: weakref.WeakKeyDictionary[asyncio.Task[Any], Slot] = (
            weakref.WeakKeyDictionary()
        )

    # -- the door's, here for the server ------------------------------------------------------
    @property
    def max_bytes(self) -> int:
        return self.config.max_bytes

    @property
    def max_connections(self) -> int:
        return self.slots.max_total

    @property
    def max_connections_per_address(self) -> int:
        return self.slots.max_per_address

    @property
    def gate(self) -> Any:
        return self.door.gate

    @property
    def tab_gate(self) -> Any:
        return self.door.tab_gate

    @property
    def refused_connections(self) -> Counter[str]:
        return self.door.refused_connections

    @property
    def rejoin_token(self) -> Callable[[str], str | None]:
        """The session token a rejoin cookie's value proves, else ``None`` (set by the server)."""
        return self.door.rejoin_token

    @rejoin_token.setter
    def rejoin_token(self, value: Callable[[str], str | None]) -> None:
        self.door.rejoin_token = value

    @property
    def page_filter(self) -> Callable[[Any, Any], Any] | None:
        """Rewrites viser's HTTP responses (``study.server.page_head``; set by the server)."""
        return self.door.page_filter

    @page_filter.setter
    def page_filter(self, value: Callable[[Any, Any], Any] | None) -> None:
        self.door.page_filter = value

    def client_host(self, connection: Any, headers: Any = None) -> str:
        """The address limits and logs use for ``connection`` (:meth:`Door.client_host`)."""
        return self.door.client_host(connection, headers)

    def accepts(self, peer: str) -> bool:
        """A new TCP connection from ``peer``: False to reset it before reading anything."""
        return self.door.accepts(peer)

    def process_request(self, inner: Callable[..., Any] | None) -> Callable[..., Any]:
        """Wrap viser's HTTP handler with the door's checks (:meth:`Door.process_request`)."""
        return self.door.process_request(inner)

    def connection_lost(self, connection: Any) -> None:
        """A connection is gone (its slot is free)."""
        self.slots.remove(connection)

    # -- lifetime ----------------------------------------------------------------------------
    def attach(self, server: viser.ViserServer) -> None:
        """Watch ``server``'s connections (``hooks.install`` calls this): start the sweeper."""
        self._server = server
        loop = viser_door.event_loop(server)
        asyncio.run_coroutine_threadsafe(self._start_sweeper(), loop).result(timeout=5)

    def before_stop(self) -> None:
        """Call before the server stops, on its loop while it still runs: ends the sweeper (a
        task left pending on a closed loop is reported as destroyed) and resets each connection
        that holds no session or whose frames wait for their share or budget. A closing
        handshake needs the peer's answer, which such a connection does not give in time (its
        reads are held back; a flood's sockets are often gone), so each held the stop for
        websockets' 10-s close timeout and its handler for its whole wait: a stop after a
        56-socket flood took 16 s and left viser's thread running. A tab that holds a session
        (or presented its rejoin token) is closed as before, "going away"."""
        server, sweeper = self._server, self._sweeper
        if server is None:
            return
        loop = viser_door.event_loop(server)

        async def wind_down() -> None:
            if sweeper is not None:
                sweeper.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await sweeper
            for slot in self.slots:
                if slot.held or not (slot.bound or slot.reserved):
                    transport = getattr(slot.connection, "transport", None)
                    if transport is not None:
                        transport.abort()

        if not loop.is_closed():
            with contextlib.suppress(RuntimeError, TimeoutError):
                asyncio.run_coroutine_threadsafe(wind_down(), loop).result(timeout=5)
        self._sweeper = None

    def detach(self) -> None:
        server, self._server = self._server, None
        loop = None if server is None else viser_door.event_loop(server)
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
                close_slot(slot, 1001)

    # -- sessions ----------------------------------------------------------------------------
    def _tab_slot(self, client_id: int) -> Slot | None:
        server = self._server
        if server is None:
            return None
        connection = viser_door.connection_of(server, client_id)
        return self.slots.get(connection) if connection is not None else None

    def bind(self, client_id: int, bound: bool = True) -> None:
        """The tab ``client_id`` now holds a session (``bound``) or no longer does: a bound tab
        is never slowed, and what the rules refuse from it is reported to ``on_bound_drop``."""
        slot = self._tab_slot(client_id)
        if slot is not None:
            slot.bound, slot.client_id = bound, client_id

    def token_of(self, client_id: int) -> str | None:
        """The rejoin token tab ``client_id`` presented at the door (``None``: none, or none
        that an open session issued)."""
        slot = self._tab_slot(client_id)
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
            wait = self._frame_wait(slot, len(raw), now)
            if wait > 0.0:
                slot.held = True
                try:
                    await _unless_lost(connection, wait)
                finally:
                    slot.held = False
            return raw

        return screened

    def _frame_wait(self, slot: Slot, size: int, now: float) -> float:
        """How long a frame of ``size`` bytes on ``slot`` waits for its share or budget."""
        config = self.config
        if not slot.bound and self.shares is not None:
            return self.shares.delay(slot.address, now, cost=1 + size // 1024)
        if slot.bound and config.bound_bytes_per_s is not None:
            if slot.budget is None:
                per_s, burst = config.bound_bytes_per_s, config.bound_bytes_burst
                slot.budget = ByteBudget(per_s=per_s, burst=burst, now=now)
            wait = slot.budget.delay(size, now)
            self.slowed += wait > 0.0
            return wait
        return 0.0

    # -- per message -------------------------------------------------------------------------
    def screened_decode(self, raw: bytes, decode: Callable[[bytes], Any]) -> Any:
        """One incoming message (``study.server.viser_door``'s incoming screen): admitted and
        screened before it becomes a message object; a refused one becomes a :class:`Dropped`
        that nothing handles."""
        self.admit()
        reason = self.screen(raw)
        if reason is not None:
            slot = self._slot()
            # a value out of range from a tab that holds a session (a handle dragged far along
            # an axis seen edge-on) is refused but never closes the tab: its volume is already
            # bounded by the rate; anything else refused counts toward closing the connection
            if not (slot is not None and slot.bound and rules.is_value_refusal(reason)):
                self.count_refusal()
            return self.refuse(reason)
        try:
            decoded = decode(raw)
        except Exception as exc:  # a field of the wrong shape for its type
            return self.refuse(f"undecodable message ({type(exc).__name__})")
        self.admitted()
        return decoded

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
        config, now = self.config, self._clock()
        if slot.rate is None:
            slot.rate = ConnectionRate(config.burst, now)
        within = slot.rate.spend(
            now, rate_per_s=config.rate_per_s, burst=config.burst, backlog_s=config.backlog_s
        )
        if not within:  # twice the burst over the rate: not a page
            self._closing(f"more than {config.rate_per_s:g} messages a second")

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
            if slot.rate.refused > self.config.max_refused:
                self._closing(f"more than {self.config.max_refused} refused messages")

    def frames_refused(self, why: str) -> None:
        """A connection broke its frame budget (``limits.FrameBudget``) and is being closed."""
        with self._lock:
            self.closed_connections += 1
        self.notes.note("frames refused", f"closed a connection that sent {why}")

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
            max_bytes=self.config.max_bytes,
            allowed=self.allowed,
            allow_share=self.config.allow_share,
            max_position_m=self.config.max_position_m,
            max_text=MAX_GUI_TEXT if slot is None or slot.bound else MAX_STRING,
        )

    def refuse(self, reason: str) -> Dropped:
        key = reason.split(":")[0].split(" (")[0]  # counted by type (a bounded set)...
        kind = rules.reason_kind(reason)  # ...and logged by kind, whatever sizes or names
        with self._lock:
            self.dropped[key] += 1
            count = self.dropped[key]
        if self.notes.due(kind):
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

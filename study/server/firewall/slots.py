"""Who holds the port's connection slots, and who gets one next.

Every websocket the door lets through holds a :class:`Slot` of one client address until its
connection is gone. A slot is *waiting* until the first message that passes the rules (a
browser's camera, sent as soon as it loads), then *open* (a tab on the join screen), *bound*
once the tab holds a session, or *reserved* when it presented a session's rejoin token at the
door (a reload of a bound tab).

Slots are shared, never hoarded:

* at most ``max_per_address`` per address and ``max_total`` in all, but a reserved tab is
  always let in (at most ``reserved_per_token`` per token: a reload overlaps its old socket;
  past that a tab with the token is an ordinary newcomer);
* when the port is full, a newcomer from an address with at least two slots fewer than the
  address holding the most unbound slots takes the oldest of those (waiting ones first): idle
  sockets from a few addresses cannot keep a new tab out, and bound or reserved tabs are never
  taken;
* a waiting slot is closed after ``greet_timeout_s`` (a page sends its camera within a second
  or two), an open one after ``idle_timeout_s`` without a message (the tab reconnects by itself
  and shows the join screen again; ``None`` for the console, whose tab may watch for hours).
"""

from __future__ import annotations

import asyncio
from collections import Counter
from dataclasses import dataclass, field
from typing import Any


@dataclass(eq=False)
class Slot:
    """One connection's place on the port."""

    address: str
    opened: float
    connection: Any = None
    token: str | None = None
    """The rejoin token it presented at the door (reserved slots only)."""
    last_seen: float = 0.0
    greeted: bool = False
    bound: bool = False
    client_id: int | None = None
    closing: bool = False
    held: bool = False
    """A frame of it waits for its share or budget (its reads are held back)."""
    rate: Any = field(default=None, repr=False)
    """Its :class:`~study.server.firewall.limits.ConnectionRate` (created on its first message)."""
    budget: Any = field(default=None, repr=False)
    """Its :class:`~study.server.firewall.shares.ByteBudget` (created once it is bound)."""

    @property
    def reserved(self) -> bool:
        return self.token is not None

    @property
    def unbound(self) -> bool:
        return not (self.bound or self.reserved or self.closing)


class Slots:
    """The slot registry of one port (touched only on the server's event loop)."""

    def __init__(
        self,
        *,
        max_total: int = 64,
        max_per_address: int = 8,
        reserved_per_token: int = 2,
        greet_timeout_s: float = 15.0,
        idle_timeout_s: float | None = 600.0,
    ) -> None:
        self.max_total = max_total
        self.max_per_address = max_per_address
        self.reserved_per_token = reserved_per_token
        self.greet_timeout_s = greet_timeout_s
        self.idle_timeout_s = idle_timeout_s
        self._slots: dict[int, Slot] = {}
        self.evicted = 0
        self.timed_out = 0

    def __len__(self) -> int:
        return sum(1 for s in list(self._slots.values()) if not s.closing)

    def __iter__(self) -> Any:
        return iter(list(self._slots.values()))

    def get(self, connection: Any) -> Slot | None:
        return self._slots.get(id(connection))

    def admit(
        self, connection: Any, address: str, *, now: float, token: str | None = None
    ) -> tuple[Slot | None, str | None]:
        """At the door: ``(evict, None)`` when ``connection`` gets a slot (``evict``: a slot to
        close for it, or ``None``), ``(None, problem)`` when it does not."""
        live = [s for s in self._slots.values() if not s.closing]
        evict = None
        if token is not None and not self.room_for_token(token):
            token = None  # see room_for_token
        if token is None:
            mine = sum(1 for s in live if s.address == address)
            if mine >= self.max_per_address:
                return None, f"too many connections from one address ({mine})"
            if len(live) >= self.max_total:
                evict = self._fair_victim(live, newcomer=mine)
                if evict is None:
                    return None, f"too many connections ({len(live)})"
        if evict is not None:
            evict.closing = True
            self.evicted += 1
        slot = Slot(address=address, opened=now, connection=connection, token=token, last_seen=now)
        self._slots[id(connection)] = slot
        return evict, None

    def room_for_token(self, token: str) -> bool:
        """Whether another connection may hold a slot kept for ``token``. Beyond that, more tabs
        of one browser (they share its cookie) come in as new tabs do, under their address's
        limits, and the page tells them the session is open elsewhere: a refusal would leave an
        honest tab "connecting" for ever."""
        live = [s for s in list(self._slots.values()) if not s.closing and s.token == token]
        return len(live) < self.reserved_per_token

    def _fair_victim(self, live: list[Slot], *, newcomer: int) -> Slot | None:
        """The oldest unbound slot (waiting ones first) of the address holding the most
        unbound slots, if it holds at least two more than the newcomer's address (taking it
        then makes the shares more even, never merely swaps them)."""
        unbound = [s for s in live if s.unbound]
        counts = Counter(s.address for s in unbound)
        if not counts:
            return None
        address, most = max(counts.items(), key=lambda item: item[1])
        if most < newcomer + 2:
            return None
        theirs = [s for s in unbound if s.address == address]
        return min(theirs, key=lambda s: (s.greeted, s.opened))

    def remove(self, connection: Any) -> Slot | None:
        return self._slots.pop(id(connection), None)

    def overdue(self, now: float) -> list[Slot]:
        """Slots to close now: waiting too long for a first message, or open and idle too long
        (marked ``closing``)."""
        due = []
        for slot in self._slots.values():
            if slot.closing or slot.bound:
                continue
            idle = self.idle_timeout_s
            if (not slot.greeted and now - slot.opened > self.greet_timeout_s) or (
                slot.greeted and idle is not None and now - slot.last_seen > idle
            ):
                slot.closing = True
                due.append(slot)
        self.timed_out += len(due)
        return due


def close_slot(slot: Slot, code: int) -> None:
    """Close ``slot``'s connection with websocket close ``code`` (on the server's event loop)."""
    connection = slot.connection
    if connection is not None and hasattr(connection, "close"):
        asyncio.get_running_loop().create_task(connection.close(code, ""))

"""The open-enrolment link of an online study: on or off, its places, one session per ID.

Off by default. The experimenter turns it on with a number of places (``serve --open-link N``
or the console); a tab whose URL carries a recruitment ID (``study.server.recruitment``) then
gets a session without a join code: a new ID is enrolled under a study pseudonym (``L0001``,
``L0002``, ...; the recruitment IDs are stored with the enrolment, never used as the
participant ID), an ID seen before gets its own session back. Places count the link's
sessions that did not withdraw (a participant who declines consent frees the place again, as
a returned submission does on Prolific).

The IDs a link enrolled are read back from the store's ``enrol`` events when the server
starts, so a restart keeps one session per ID. Thread-safe.

Bots: anyone with the link can make up IDs, and a script from 8 addresses once filled 50
places in 20 s. One address gets at most ``per_address`` new IDs in ``window_s`` (3 an hour, 0: no limit;
people behind one address -- a household, a carrier's shared address -- rarely start the
same study within the hour; an ID seen before is never refused by it). A script with many
addresses still fills places; the console shows them, declined or withdrawn sessions give
them back, and so do sessions left before consent for ten minutes (``study.server.link_places``).
"""

from __future__ import annotations

import re
import threading
import time
from collections import deque

from study.errors import StudyError
from study.server.recruitment import Recruitment
from study.store import Store

LINK_PARTICIPANT = re.compile(r"L(\d{4,})")
LINK_SOURCE = "link"
RELEASED = "link_place_released"
"""The event that records a session's place given back (``study.server.link_places``)."""
RETAKEN = "link_place_retaken"
"""The event that records its recruitment ID coming back: the session holds a place again."""


class LinkClosed(StudyError, RuntimeError):
    """The link does not take new participants now (off, or every place taken)."""


class OpenLink:
    """See module docstring."""

    def __init__(
        self,
        store: Store,
        *,
        enabled: bool = False,
        cap: int = 0,
        per_address: int = 3,
        window_s: float = 3600.0,
    ) -> None:
        self.store = store
        self.per_address = per_address
        self.window_s = window_s
        self._new: dict[str, deque[float]] = {}
        """When each address last had a new ID enrolled (at most ``per_address`` kept)."""
        self._lock = threading.Lock()
        self.enabled = False
        self.cap = 0
        self._by_key: dict[str, str] = {}
        self._recruitment: dict[str, Recruitment] = {}
        self._released: set[str] = set()
        """Participants whose place was given back (until they come back)."""
        self.refused: dict[str, int] = {"off": 0, "full": 0, "address": 0}
        """New IDs refused since the server started, by why: the link off, every place taken,
        the address's new IDs for the hour used up (the console shows them)."""
        for event in store.events():
            if event.kind == RELEASED and event.participant:
                self._released.add(event.participant)
            elif event.kind in (RETAKEN, "participant_connected"):
                self._released.discard(event.participant or "")
            rec = event.detail.get("recruitment") if event.kind == "enrol" else None
            if isinstance(rec, dict) and event.participant:
                try:
                    recruitment = Recruitment(tuple((str(k), str(v)) for k, v in rec.items()))
                    key = recruitment.key
                except (StopIteration, TypeError):
                    continue
                self._by_key[key] = event.participant
                self._recruitment[event.participant] = recruitment
        self.configure(enabled=enabled, cap=cap)

    def configure(self, *, enabled: bool, cap: int) -> None:
        if isinstance(cap, bool) or not isinstance(cap, int) or not 0 <= cap <= 100_000:
            raise ValueError(f"places must be a whole number 0..100000, got {cap!r}")
        if enabled and cap == 0:
            raise ValueError("give the open link at least one place (e.g. --open-link 20)")
        with self._lock:
            self.enabled, self.cap = bool(enabled), cap

    def in_use(self) -> bool:
        """On, or it enrolled someone (who may come back to their session or end screen)."""
        with self._lock:
            return self.enabled or bool(self._by_key)

    def participant_for(self, recruitment: Recruitment) -> str | None:
        """The participant a recruitment ID enrolled before, if any."""
        with self._lock:
            return self._by_key.get(recruitment.key)

    def recruitment_of(self, participant: str) -> Recruitment | None:
        with self._lock:
            return self._recruitment.get(participant)

    def used(self) -> int:
        """Places taken: the link's sessions that did not withdraw and were not given back."""
        with self._lock:
            mine = set(self._by_key.values()) - self._released
        return sum(s.participant in mine and s.status != "withdrawn" for s in self.store.sessions())

    def release(self, participant: str) -> None:
        """Give ``participant``'s place back (their session was left before consent)."""
        with self._lock:
            self._released.add(participant)

    def returned(self, participant: str) -> None:
        """``participant`` came back by the link: they hold a place again."""
        with self._lock:
            self._released.discard(participant)

    def released(self) -> frozenset[str]:
        with self._lock:
            return frozenset(self._released)

    def claim(self, recruitment: Recruitment, *, address: str = "unknown") -> str:
        """A new study pseudonym for ``recruitment`` from ``address`` (call ``taken`` once it
        is enrolled); :class:`LinkClosed` while the link is off or full, or ``address`` had
        its new IDs for now."""
        if not self.enabled:
            self._refuse("off")
            raise LinkClosed("the open link is off")
        if self.used() >= self.cap:
            self._refuse("full")
            raise LinkClosed(f"all {self.cap} places are taken")
        if self.per_address > 0 and self._recent(address, time.monotonic()) >= self.per_address:
            self._refuse("address")
            raise LinkClosed(
                f"{self.per_address} new IDs from one address within {self.window_s:g} s"
            )
        ids = (p.participant for p in self.store.participants())
        numbers = [int(m[1]) for p in ids if (m := LINK_PARTICIPANT.fullmatch(p))]
        return f"L{max(numbers, default=0) + 1:04d}"

    def _refuse(self, why: str) -> None:
        with self._lock:
            self.refused[why] += 1

    def taken(
        self, participant: str, recruitment: Recruitment, *, address: str = "unknown"
    ) -> None:
        with self._lock:
            self._by_key[recruitment.key] = participant
            self._recruitment[participant] = recruitment
            if address != "unknown" and self.per_address > 0:
                self._new.setdefault(address, deque(maxlen=self.per_address)).append(
                    time.monotonic()
                )

    def _recent(self, address: str, now: float) -> int:
        """New IDs ``address`` had enrolled within the window (forgetting quiet addresses)."""
        with self._lock:
            if len(self._new) > 4096:
                for quiet in [a for a, q in self._new.items() if now - q[-1] > self.window_s]:
                    del self._new[quiet]
            stamps = self._new.get(address, ())
            return sum(1 for t in stamps if now - t <= self.window_s)


__all__ = ["LINK_SOURCE", "RELEASED", "RETAKEN", "LinkClosed", "OpenLink"]

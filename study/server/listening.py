"""Whether the participant port has been listening: its event loop on time, or behind.

Held keys are let go when the page's key state stops arriving
(``ParticipantPage.expire_keys``): a stalled tab must not leave the arm moving. But a state
that waits in the server's own backlog -- its event loop starved of CPU or of the GIL, a flood
being screened -- did arrive: the tab is not silent, the server was deaf. A beat scheduled on
the loop every ``period_s`` notes when it ran more than ``late_s`` late (or is overdue now),
and a tab's silence is counted only while the server listened::

    silent = now - max(heard, deaf_until)

so a tab that resends on time keeps its keys however slow the server is; a tab that stops
resending loses them ``max_age`` after the server was last behind (bounded by
``ParticipantPage``'s ``DEAF_LIMIT_S``).
"""

from __future__ import annotations

import asyncio
import contextlib
import time

BEAT_PERIOD_S = 0.05
"""How often the beat runs on the loop (20 wake-ups a second: nothing beside the messages)."""

LATE_S = 0.1
"""A beat this much later than due means the loop was behind: what it reads was waiting."""


class ListeningClock:
    """A beat on ``loop``; ``silent_s`` is read from any thread (the control loop's)."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        *,
        period_s: float = BEAT_PERIOD_S,
        late_s: float = LATE_S,
    ) -> None:
        self.period_s = period_s
        self.late_s = late_s
        self._loop = loop
        self._due = time.monotonic() + period_s
        self.deaf_until = time.monotonic()
        """The last time the loop was seen behind (a beat ``late_s`` late)."""
        self._handle: asyncio.TimerHandle | None = None
        self._stopped = False
        loop.call_soon_threadsafe(self._beat)

    def _beat(self) -> None:
        now = time.monotonic()
        if now - self._due > self.late_s:
            self.deaf_until = now
        if self._stopped:
            return
        self._due = now + self.period_s
        self._handle = self._loop.call_later(self.period_s, self._beat)

    def silent_s(self, heard_at: float, now: float | None = None) -> float:
        """Seconds since ``heard_at`` (``time.monotonic``) during which the server listened on
        time: ``now - max(heard_at, deaf_until)``, 0 while the loop is behind right now."""
        now = time.monotonic() if now is None else now
        if now - self._due > self.late_s:
            return 0.0  # the beat is overdue: the loop is behind at this moment
        return max(0.0, now - max(heard_at, self.deaf_until))

    def stop(self) -> None:
        """No more beats (the loop may already be closed: then there is nothing to cancel)."""
        self._stopped = True
        handle = self._handle
        if handle is not None:
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(handle.cancel)

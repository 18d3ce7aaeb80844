"""Finished sessions leave the study server: their threads end, their memory goes.

A session whose participant has finished (completed, withdrawn or ended: ``FINAL_STATUSES``)
keeps its page thread, its view and its place in the server's registry only while a tab shows
its last screen, and for ``FINISHED_GRACE_S`` after that tab left (or after it was over, if no
tab held it then): a reload within the grace presents the session's rejoin cookie and gets the
last screen again. Then the session is closed and dropped (``StudyServer.drop_finished``, from
the sweeper of ``study.server.link_places``), so a server that serves thousands of
participants holds only the sessions in progress. Its code and cookie are then nobody's: a tab
that types or presents them gets what any wrong code gets. An open link's participant comes
back by their recruitment ID instead, and gets their end screen from the store as before.

The console lists the last ``RETIRED_KEPT`` of them (``Retired``: the row they had, a few hundred
bytes) and shows the selected one from the store (``live.console.finished_detail``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from study.protocol import Protocol
from study.server.console_model import SessionDetail, SessionSummary
from study.server.live import LiveSession
from study.server.live.console import finished_detail
from study.store import Store

FINISHED_GRACE_S = 300.0
"""How long a finished session stays after its last tab left: five minutes, longer than a lost
connection takes to be noticed (the websocket's ping interval and timeout, 40 s) and a reload
after it, or the end screen's way back to the recruitment site (8 s); short enough that an open
link serving a participant a minute holds about five finished sessions at a time."""
RETIRED_KEPT = 500
"""Finished sessions the console keeps listing once they left (the newest; the store has all)."""


def finished_and_left(
    sessions: Iterable[LiveSession], *, grace_s: float, now: float
) -> list[LiveSession]:
    """The sessions that have been over, with no tab on their last screen, for at least
    ``grace_s`` seconds at ``now`` (``time.monotonic()``)."""
    return [
        live
        for live in sessions
        if (left := live.over_and_left_s(now)) is not None and left >= grace_s
    ]


@dataclass(frozen=True)
class Retired:
    """A finished session the server let go: its last row in the console's list."""

    summary: SessionSummary
    recruitment: tuple[tuple[str, str], ...] = ()

    @classmethod
    def of(cls, live: LiveSession) -> Retired:
        """``live``'s record (it has no tab: ``finished_and_left``)."""
        return cls(summary=live.summary(), recruitment=live.recruitment)

    @property
    def code(self) -> str:
        return self.summary.code

    @property
    def participant(self) -> str:
        return self.summary.participant

    def detail(self, store: Store, protocol: Protocol) -> SessionDetail:
        """What the console shows of it, read from the store."""
        return finished_detail(store, protocol, self.summary, recruitment=self.recruitment)


__all__ = ["FINISHED_GRACE_S", "RETIRED_KEPT", "Retired", "finished_and_left"]

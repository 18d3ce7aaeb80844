"""One live study session on the server, in parts that each read in one sitting.

``live_session.LiveSession`` connects a ``study.session.Session`` to one participant tab and to time;
its parts: ``view.LiveView`` (snapshots and the render loop), ``controls.LiveInput`` (the
participant's input, frozen while paused), ``control_faults.ControlFaults`` (a tick that raised),
``screens.show_screen`` (the session's screen on the page), ``texts`` (what the participant
reads around a run), ``console`` (the experimenter's summary and detail). ``session_factory``
opens the sessions the study server serves.
"""

from __future__ import annotations

import secrets
from collections.abc import Mapping
from dataclasses import dataclass

from study.protocol import Protocol
from study.server.live.live_session import LiveSession
from study.session import FINAL_STATUSES, Session
from study.store import Store


@dataclass(frozen=True)
class SessionFactory:
    """Opens the live sessions of one store and protocol (``session_factory``)."""

    store: Store
    protocol: Protocol

    def __call__(
        self,
        participant: str,
        *,
        code: str,
        title: str,
        render_hz: float,
        recruitment: Mapping[str, str] | None = None,
    ) -> LiveSession:
        """Open ``participant``'s session: enrol a new ID (with the ``recruitment`` IDs of an
        open link, if any), or reopen an unfinished one."""
        if self.store.has_participant(participant):
            session = Session.reopen(self.store, self.protocol, participant)
        else:
            session = Session.enrol(
                self.store,
                self.protocol,
                participant,
                seed=secrets.randbelow(2**31),
                recruitment=recruitment,
            )
        live = LiveSession(session, code=code, title=title, render_hz=render_hz)
        if recruitment:
            live.recruitment = tuple(recruitment.items())
        return live

    def reopenable(self, *, open_now: set[str] | frozenset[str] = frozenset()) -> list[str]:
        """Participants whose session is unfinished and not in ``open_now`` (a server restart
        or crash left them): the console offers to reopen them."""
        return [
            s.participant
            for s in self.store.sessions()
            if s.status not in FINAL_STATUSES and s.participant not in open_now
        ]


def session_factory(store: Store, protocol: Protocol) -> SessionFactory:
    """Open ``participant``'s session: enrol a new ID, or reopen an unfinished one."""
    return SessionFactory(store, protocol)


__all__ = ["LiveSession", "SessionFactory", "session_factory"]

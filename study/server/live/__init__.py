"""One live study session on the server, in parts that each read in one sitting.

``session.LiveSession`` connects a ``study.session.Session`` to one participant tab and to time;
its parts: ``view.LiveView`` (snapshots and the render loop), ``controls.LiveInput`` (the
participant's input, frozen while paused), ``faults.ControlFaults`` (a tick that raised),
``screens.show_screen`` (the session's screen on the page), ``texts`` (what the participant
reads around a run), ``console`` (the experimenter's summary and detail). ``session_factory``
opens the sessions the study server serves.
"""

from __future__ import annotations

import secrets
from collections.abc import Callable

from study.protocol import Protocol
from study.server.live.session import LiveSession
from study.session import Session
from study.store import Store

SessionFactory = Callable[..., LiveSession]


def session_factory(store: Store, protocol: Protocol) -> SessionFactory:
    """Open ``participant``'s session: enrol a new ID, or reopen an unfinished one."""

    def make(participant: str, *, code: str, title: str, render_hz: float) -> LiveSession:
        if store.has_participant(participant):
            session = Session.reopen(store, protocol, participant)
        else:
            session = Session.enrol(store, protocol, participant, seed=secrets.randbelow(2**31))
        return LiveSession(session, code=code, title=title, render_hz=render_hz)

    return make


__all__ = ["LiveSession", "SessionFactory", "session_factory"]

"""The live session logs its UI events through ``Session.record_event``: only while it holds
the participant's lease, never into a session another process has taken over or it has closed."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from study.protocol import Protocol, load_protocol
from study.server.live import LiveSession
from study.session import Session, open_store
from study.store import Store


@pytest.fixture(scope="module")
def protocol(protocol_path: Path) -> Protocol:
    return load_protocol(protocol_path)


@pytest.fixture
def store(tmp_path: Path, protocol: Protocol) -> Store:
    s = open_store(tmp_path / "study.db", protocol)
    yield s
    s.close()


def kinds(store: Store) -> list[str]:
    return [e.kind for e in store.events()]


def test_ui_events_are_written_while_the_lease_is_held(store: Store, protocol: Protocol) -> None:
    live = LiveSession(Session.enrol(store, protocol, "P01", seed=1), code="1234", title="t")
    try:
        live._event("participant_connected", {"client": 3})
        event = [e for e in store.events() if e.kind == "participant_connected"]
        assert len(event) == 1 and event[0].detail == {"client": 3}
    finally:
        live.close()


def test_no_ui_event_after_another_process_took_the_session_over(
    store: Store, protocol: Protocol
) -> None:
    live = LiveSession(Session.enrol(store, protocol, "P01", seed=1), code="1234", title="t")
    try:
        with store.transaction() as tx:  # another host's process took the session over
            tx.cur.execute("UPDATE leases SET token = 'other', pid = 1 WHERE participant = 'P01'")
        before = kinds(store)
        live._event("participant_disconnected", {"client": 3})  # logged, not raised
        assert kinds(store) == before
        assert live.log[-1].endswith("participant_disconnected")  # the console still shows it
    finally:
        live.close()


def test_no_ui_event_into_a_closed_session(store: Store, protocol: Protocol) -> None:
    session = Session.enrol(store, protocol, "P01", seed=1)
    live = LiveSession(session, code="1234", title="t")
    try:
        session.close()
        before = kinds(store)
        live._event("second_tab_refused", {"client": 4})
        assert kinds(store) == before
    finally:
        live.close()


def test_a_tab_closed_after_the_session_ended_is_logged_as_such(
    store: Store, protocol: Protocol, caplog: pytest.LogCaptureFixture
) -> None:
    """The server log says the session is over, not "reopen the session" (an experimenter
    reading it after a finished session would look for something to reopen)."""
    session = Session.enrol(store, protocol, "P01", seed=1)
    live = LiveSession(session, code="1234", title="t")
    try:
        session.end(reason="test: the session is over")
        session.close()
        with caplog.at_level(logging.INFO, logger="study.server.live"):
            live._event("participant_disconnected", {"client": 3})
        lines = [r.getMessage() for r in caplog.records]
        assert "event participant_disconnected not recorded: the session is over" in lines, lines
    finally:
        live.close()

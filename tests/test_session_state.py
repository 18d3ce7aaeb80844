"""One owner of run state: the session says whether it is paused (and by whom); the run, its
trial and the views follow it; the experimenter actions it offers are the ones it accepts."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from study.protocol import Protocol, parse_protocol
from study.session import EXPERIMENTER_ACTIONS, Session, SessionStateError, open_store
from study.store import Store
from tests.protocol_copies import ratings_only
from tests.support.sessions import PROTOCOL_PATH, enrol, finish_run, to_step


@pytest.fixture(scope="module")
def protocol() -> Protocol:
    return parse_protocol(ratings_only(), path=PROTOCOL_PATH)


@pytest.fixture
def store(tmp_path: Path, protocol: Protocol) -> Iterator[Store]:
    s = open_store(tmp_path / "study.db", protocol)
    yield s
    s.close()


def test_pause_is_the_sessions_and_the_run_and_trial_follow_it(
    store: Store, protocol: Protocol
) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    run = session.start_trial(input_source=None)
    assert run.tick() is not None
    session.pause(cause="tab_lost")
    assert session.paused and session.paused_by == "tab_lost"
    assert run.paused and run.trial._paused  # type: ignore[attr-defined]
    assert session.overview().paused and session.screen().paused
    assert run.tick() is None  # no tick while the session is paused
    session.resume()
    assert not session.paused and session.paused_by is None
    assert not run.paused and not run.trial._paused  # type: ignore[attr-defined]
    assert run.tick() is not None
    session.pause()
    assert session.paused_by == "experimenter"
    session.end(reason="test")
    assert not session.paused and not session.overview().paused and run.over
    session.close()


def test_a_pause_between_trials_holds_the_next_start(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    session.pause()
    with pytest.raises(SessionStateError, match="paused"):
        session.start_trial(input_source=None)
    session.resume()
    finish_run(session)
    session.close()


def _sessions_at(store: Store, protocol: Protocol) -> dict[str, Callable[[str], Session]]:
    """Ways to bring a fresh participant to a screen with a running or finished trial."""

    def running(pid: str) -> Session:
        s = enrol(store, protocol, pid)
        to_step(s, "ready")
        s.start_trial(input_source=None)
        return s

    def rated(pid: str) -> Session:
        s = enrol(store, protocol, pid)
        to_step(s, "ready")
        finish_run(s)
        return s

    def waiting(pid: str) -> Session:
        return enrol(store, protocol, pid)

    return {"running": running, "after a run": rated, "waiting": waiting}


def test_every_offered_experimenter_action_is_accepted(store: Store, protocol: Protocol) -> None:
    """The console offers ``overview().experimenter_actions``: each must work when clicked, and
    they come in the one order every part of the project lists them in."""
    n = 0
    for where, make in _sessions_at(store, protocol).items():
        probe = make(f"P{n:02d}")
        offered = probe.overview().experimenter_actions
        probe.close()
        assert offered == tuple(a for a in EXPERIMENTER_ACTIONS if a in offered), where
        for action in offered:
            n += 1
            session = make(f"P{n:02d}")
            call = getattr(session, action)
            if action in ("redo", "skip", "withdraw", "end"):
                call(reason="test")
            else:
                call()
            session.close()
        n += 1
    assert n > 8


def test_question_screens_carry_the_protocols_own_items(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    to_step(session, "questions", questionnaire="after_training")
    items = session.screen().items
    assert items == protocol.questionnaire.after_training
    assert all(i.anchors == i.scale.anchors and i.points == i.scale.points for i in items)
    session.close()

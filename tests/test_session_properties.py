"""Random sequences of participant and experimenter actions never corrupt a session.

Each action either succeeds or raises a typed ``SessionError``/``StoreError`` that leaves the
session (cursor, status) and the store (every table's row count) exactly as they were. Whatever
happened, a reopened session runs to the end with one completed attempt per trial step that was
not skipped.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from study.protocol import load_protocol
from study.session import Session, open_store
from study.session.answers import ScriptedAnswers
from study.session.errors import SessionError
from study.session.headless import run_headless
from study.store import TABLES, Store, StoreError
from tests.support.sessions import stub_factory, valid_answers

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = load_protocol(ROOT / "protocols" / "dragan2013.toml")

ACTIONS = (
    "start", "agree", "run_trial", "start_and_tick", "tick", "answer", "answer_bad", "answer_unknown",
    "finish", "pause", "resume", "redo", "skip", "withdraw", "end", "close_reopen",
)  # fmt: skip


def counts(store: Store) -> dict[str, int]:
    return {t: int(store.conn.execute(f"SELECT count(*) FROM {t}").fetchone()[0]) for t in TABLES}


def act(session: Session, action: str) -> Session:
    if action == "start":
        session.start()
    elif action == "agree":
        session.agree()
    elif action == "run_trial":
        session.start_trial(input_source=None).run_to_end()
    elif action == "start_and_tick":
        session.start_trial(input_source=None).tick()
    elif action == "tick":
        if session.active_run is not None:
            session.active_run.tick()
    elif action == "answer":
        items = session.screen().items
        session.answer(dict(list(valid_answers(items, likert=3).items())[:2]) or {"helpful": 3})
    elif action == "answer_bad":
        session.answer({"helpful": 9})
    elif action == "answer_unknown":
        session.answer({"favourite_colour": 2})
    elif action == "finish":
        session.finish()
    elif action == "pause":
        session.pause()
    elif action == "resume":
        session.resume()
    elif action == "redo":
        session.redo(reason="random redo")
    elif action == "skip":
        session.skip(reason="random skip")
    elif action == "withdraw":
        session.withdraw(reason="random withdraw")
    elif action == "end":
        session.end(reason="random end")
    return session


@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(st.lists(st.sampled_from(ACTIONS), min_size=1, max_size=40))
def test_random_actions_keep_the_session_consistent(actions: list[str]) -> None:
    with tempfile.TemporaryDirectory() as d:
        store = open_store(Path(d) / "s.db", PROTOCOL, synchronous="NORMAL")
        session = Session.enrol(store, PROTOCOL, "P01", trial_factory=stub_factory)
        try:
            for action in actions:
                if action == "close_reopen":
                    session.close()
                    if session.finished:
                        break
                    session = Session.reopen(store, PROTOCOL, "P01", trial_factory=stub_factory)
                    continue
                before = (session.cursor, session.status, session.phase(), counts(store))
                try:
                    act(session, action)
                except (SessionError, StoreError):
                    after = (session.cursor, session.status, session.phase(), counts(store))
                    assert after == before, f"{action} failed but changed the session"
                trials = store.trials()
                completed = [t.step for t in trials if t.status == "completed"]
                assert len(completed) == len(set(completed)), "a step completed twice"
                assert 0 <= session.cursor <= len(session.plan)
                if session.finished:
                    assert session.phase() == "done"
            session.close()
            status = store.session("P01").status
            if status in ("withdrawn", "ended"):
                return
            session = Session.reopen(store, PROTOCOL, "P01", trial_factory=stub_factory)
            if session.screen().paused:
                session.resume()
            report = run_headless(session, answerer=ScriptedAnswers(seed=0))
            assert report.status == "completed"
            trials = store.trials()
            skipped = {s for e in store.events() if e.kind == "skip" for s in e.detail["steps"]}
            trial_steps = [s.index for s in session.plan.steps if s.kind == "trial"]
            for step in trial_steps:
                done = [t for t in trials if t.step == step and t.status == "completed"]
                assert len(done) == (0 if step in skipped else 1), step
            assert store.integrity_check() == "ok"
        finally:
            session.close()
            store.close()

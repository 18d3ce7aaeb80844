"""The session state machine: order of steps, blinding, experimenter actions, bad input.

Trials here are ``StubTrial``s (a fixed number of ticks, a chosen outcome) so the state machine
is tested in milliseconds; ``test_session_run.py`` runs whole sessions with the real trial.
"""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import threading
from pathlib import Path

import numpy as np
import pytest

from study.protocol import (
    Protocol,
    load_protocol,
    parse_protocol,
)
from study.session import Session, open_store
from study.session.answers import ScriptedAnswers
from study.session.errors import (
    InvalidAnswerError,
    MissingReasonError,
    SessionClosedError,
    SessionError,
    SessionStateError,
    UnknownItemError,
)
from study.session.headless import run_headless
from study.store import (
    DuplicateParticipantError,
    InvalidParticipantIdError,
    ProtocolMismatchError,
    SessionLockedError,
    Store,
    StoreError,
    UnknownParticipantError,
)
from tests.protocol_copies import ratings_only
from tests.support.sessions import (
    PROTOCOL_PATH,
    enrol,
    finish_run,
    stub_factory,
    to_step,
)


@pytest.fixture(scope="module")
def protocol() -> Protocol:
    """The paper's protocol asking its rating-scale items only (the state machine's steps are
    the paper's); ``shipped`` is the file as shipped, with the questions asked once."""
    return parse_protocol(ratings_only(), path=PROTOCOL_PATH)


@pytest.fixture(scope="module")
def shipped() -> Protocol:
    return load_protocol(PROTOCOL_PATH)


@pytest.fixture
def store(tmp_path: Path, protocol: Protocol) -> Store:
    s = open_store(tmp_path / "study.db", protocol)
    yield s
    s.close()


def test_whole_session_in_order_with_every_transition_logged(
    tmp_path: Path, shipped: Protocol
) -> None:
    store = open_store(tmp_path / "shipped.db", shipped)
    session = enrol(store, shipped, demographics={"age": 30})
    seen: list[tuple[str, str | None, str | None]] = []
    session.add_listener(lambda s: seen.append((s.phase, s.questionnaire, s.progress.text)))
    assert session.screen().phase == "waiting"
    report = run_headless(session, answerer=ScriptedAnswers(seed=1))
    assert report.status == "completed" and report.trials_completed == 11 and report.ratings == 31
    trials = store.trials(participant="P01")
    assert [t.phase for t in trials] == ["training"] * 3 + ["task"] * 8
    assert [t.mode for t in trials[:3]] == ["none"] * 3
    assert [t.position for t in trials[3:]] == list(range(1, 9))
    schedule = store.assignments("P01")
    assert [(t.task, t.mode, t.run) for t in trials[3:]] == [
        (a.task, a.mode, a.run) for a in schedule
    ]
    # each task's two runs are consecutive, in the two modes, first then second
    for i in range(3, 11, 2):
        assert trials[i].task == trials[i + 1].task
        assert {trials[i].mode, trials[i + 1].mode} == {"timid", "aggressive"}
        assert (trials[i].run, trials[i + 1].run) == ("first", "second")
    ratings = store.ratings(participant="P01")
    assert [r.item for r in ratings[:3]] == ["helpful", "matched", "teammate"]
    assert all(r.phase == "training" and r.mode == "none" for r in ratings[:3])
    prefs = [r for r in ratings if r.item == "preference"]
    assert len(prefs) == 4 and all(r.run is None and r.mode is None for r in prefs)
    per_run = [r for r in ratings[3:] if r.item != "preference"]
    assert {(r.task, r.mode) for r in per_run} == {(t.task, t.mode) for t in trials[3:]}
    assert all(r.trial_id is not None for r in per_run)
    kinds = [e.kind for e in store.events(participant="P01")]
    assert kinds[:3] == ["enrol", "start", "consent"]
    assert kinds.count("trial_start") == kinds.count("trial_end") == 11
    assert kinds.count("answer") == 16 and kinds[-1] == "finish"
    assert store.session("P01").status == "completed"
    # progress and screen order as the participant saw them
    # practice runs and the main part's runs counted apart, as the consent counts them
    assert ("ready", None, "Practice run 3 of 3") in seen
    assert ("questions", "after_training", "") in seen
    assert ("ready", None, "Run 1 of 8") in seen and ("questions", "closing", "") in seen
    # a run's number above the questions about that run (or its task's two), above no others
    assert ("questions", "after_run", "Run 1 of 8") in seen
    assert ("questions", "after_task", "Run 2 of 8") in seen
    assert ("questions", "between_tasks", "") in seen
    assert not any("Trial" in text or "of 11" in text for _, _, text in seen)
    moments = [q for p, q, _ in seen if p == "questions"]
    assert moments[0] == "before_training" and moments[-1] == "closing"
    assert (
        moments.index("between_tasks") == 1 + 1 + 2 * 3
    )  # after the second task (2 runs + preference each)
    assert seen[-1][0] == "done"
    assert store.demographics("P01") == {"age": 30}
    answers = {a.item: a for a in store.answers(participant="P01")}
    assert list(answers) == [i.id for i in shipped.questionnaire.once_items]
    assert answers["keep_data"].value == shipped.questionnaire.retention.keep
    assert answers["attention"].kind == "attention" and answers["attention"].value == "Somewhat"
    assert answers["comment"].value is None  # optional, left empty
    assert 0 <= answers["game_hours"].number <= 100
    assert all(
        a.questionnaire in ("before_training", "between_tasks", "closing") for a in answers.values()
    )
    session.close()
    store.close()


def test_screens_never_name_a_condition(tmp_path: Path, shipped: Protocol) -> None:
    store = open_store(tmp_path / "shipped.db", shipped)
    session = enrol(store, shipped)
    words = shipped.condition_words
    screens = [session.screen()]
    session.add_listener(screens.append)
    run_headless(session, answerer=ScriptedAnswers(seed=2))
    # start, consent, 11 trial starts and ends, 16 answer pages, finish
    assert len(screens) == 1 + 41
    for screen in screens:
        text = json.dumps(dataclasses.asdict(screen)).lower()
        for word in words:
            assert word not in text, f"{word!r} on the participant's screen {screen}"
    overview = session.overview()
    assert overview.status == "completed" and overview.schedule[0][3] in ("timid", "aggressive")
    session.close()
    store.close()


def test_invalid_actions_raise_and_leave_state_untouched(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    events = len(store.events())
    with pytest.raises(SessionStateError, match="cannot agree on the waiting screen"):
        session.agree()
    with pytest.raises(SessionStateError, match="cannot pause: the session is waiting"):
        session.pause()
    session.start()
    with pytest.raises(SessionStateError, match="participant actions valid now: agree"):
        session.start_trial(input_source=None)
    with pytest.raises(SessionStateError, match="cannot answer"):
        session.answer({"helpful": 3})
    with pytest.raises(SessionStateError, match="skip applies to trials and questions"):
        session.skip(reason="no")
    with pytest.raises(SessionStateError, match="nothing to redo"):
        session.redo(reason="no")
    with pytest.raises(SessionStateError, match="not paused"):
        session.resume()
    assert session.cursor == 0 and len(store.events()) == events + 1  # only "start"
    session.close()


def test_answers_outside_scale_or_unknown_items_store_nothing(
    store: Store, protocol: Protocol
) -> None:
    session = enrol(store, protocol)
    to_step(session, "questions", questionnaire="after_training")
    before = (session.cursor, len(store.ratings()), len(store.events()))
    for bad in ({"helpful": 8}, {"helpful": 0}, {"helpful": 3.5}, {"helpful": "4"}):
        with pytest.raises(InvalidAnswerError, match="helpful"):
            session.answer({"matched": 4, **bad})
    with pytest.raises(UnknownItemError, match="'preference' is not asked here"):
        session.answer({"preference": 4})
    with pytest.raises(UnknownItemError, match="'colour' is not asked here"):
        session.answer({"helpful": 4, "colour": 2})
    with pytest.raises(InvalidAnswerError, match="no answers given"):
        session.answer({})
    assert (session.cursor, len(store.ratings()), len(store.events())) == before
    # partial answers are kept and the remaining ones stay on screen
    screen = session.answer({"helpful": 6})
    assert [i.id for i in screen.items] == ["matched", "teammate"]
    with pytest.raises(UnknownItemError, match="'helpful' was already answered"):
        session.answer({"helpful": 5})
    screen = session.answer({"matched": 5, "teammate": 7})
    assert screen.phase == "ready" and screen.progress.text == "Run 1 of 8"
    assert [(r.item, r.value) for r in store.ratings()] == [
        ("helpful", 6),
        ("matched", 5),
        ("teammate", 7),
    ]
    session.close()


def test_pause_and_resume_a_running_trial(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    run = session.start_trial(input_source=None)
    assert session.screen().phase == "running" and run.tick() is not None
    screen = session.pause()
    assert screen.paused and screen.actions == () and "paused" in screen.text
    assert run.tick() is None and run.ticks == 1
    with pytest.raises(SessionStateError, match="paused"):
        session.pause()
    session.resume()
    assert run.run_to_end() is not None
    kinds = [e.kind for e in store.events()]
    assert kinds[-4:] == ["trial_start", "pause", "resume", "trial_end"]
    session.record_event("tab_connected", {"client": 3})
    assert store.events()[-1].kind == "tab_connected"
    assert store.events()[-1].detail == {"client": 3}
    with pytest.raises(SessionError, match="JSON-serialisable"):
        session.record_event("input_rejected", {"target": np.zeros(3)})
    assert store.events()[-1].kind == "tab_connected"
    assert store.trial(run.trial_id).ticks == 5 and store.sample_count(run.trial_id) == 5
    session.close()


def test_redo_keeps_the_failed_attempt(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    run = session.start_trial(input_source=None)
    run.tick()
    run.tick()
    with pytest.raises(MissingReasonError):
        session.redo(reason=" ")
    screen = session.redo(reason="participant sneezed")
    assert screen.phase == "ready" and run.over and run.tick() is None
    finish_run(session)  # attempt 2 completes; cursor at training run 2
    session.redo(reason="camera glitch")  # redo the completed run just before
    assert session.cursor == 1
    finish_run(session)  # attempt 3
    attempts = [(t.step, t.attempt, t.status, t.outcome) for t in store.trials()]
    assert attempts == [
        (1, 1, "redone", "aborted"),
        (1, 2, "redone", "success"),
        (1, 3, "completed", "success"),
    ]
    assert store.sample_count(1) == 2  # the aborted attempt's samples are kept
    to_step(session, "questions", questionnaire="after_training")
    session.answer({"helpful": 3})
    with pytest.raises(SessionStateError, match="already started or been answered"):
        session.redo(reason="too late")
    session.close()


def test_skip_a_run_skips_its_items_and_the_preference(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    with pytest.raises(MissingReasonError, match="skip needs a reason"):
        session.skip(reason="")
    for _ in range(3):
        finish_run(session)
    session.skip(reason="baseline form not available")  # skip the baseline items
    assert session.screen().phase == "ready" and session.screen().progress.text == "Run 1 of 8"
    first = session.plan[session.cursor]
    session.skip(reason="robot fault")  # skip the task's first run (not started)
    screen = session.screen()
    assert screen.phase == "ready" and screen.progress.text == "Run 2 of 8"
    run = session.start_trial(input_source=None)
    run.tick()
    session.skip(reason="robot fault again")  # skip the second run while running
    screen = session.screen()
    # both runs' items and the preference are skipped: the next task's first run is next
    assert screen.phase == "ready" and screen.progress.text == "Run 3 of 8"
    task_trials = [t for t in store.trials() if t.phase == "task"]
    assert [(t.task, t.status, t.outcome) for t in task_trials] == [
        (first.task, "skipped", None),
        (first.task, "skipped", "aborted"),
    ]
    skip_events = [e for e in store.events() if e.kind == "skip"]
    assert [e.detail["reason"] for e in skip_events][-1] == "robot fault again"
    # skipped steps survive a restart
    session.close()
    again = Session.reopen(store, protocol, "P01", trial_factory=stub_factory)
    again.start()
    assert again.screen().progress.text == "Run 3 of 8"
    report = run_headless(again, answerer=ScriptedAnswers(seed=3))
    assert report.trials_completed == 9 and report.ratings == 3 * 6 + 3
    again.close()


def test_practice_items_fit_practice_and_go_with_every_practice_run(
    store: Store, protocol: Protocol
) -> None:
    """After practice runs the items are introduced as being about the practice runs (not
    "the run you just finished"); when every practice run is skipped they are not asked."""
    done = enrol(store, protocol)
    to_step(done, "ready")
    done.skip(reason="participant knows the task")  # one practice run skipped: items stay
    finish_run(done)
    finish_run(done)
    screen = done.screen()
    assert screen.phase == "questions" and screen.questionnaire == "after_training"
    assert screen.text == protocol.texts.instructions["after_training"].strip()
    assert "practice runs" in screen.text and "run you just finished" not in screen.text
    done.close()

    skipped = enrol(store, protocol, "P02")
    to_step(skipped, "ready")
    for k in range(3):
        assert skipped.screen().progress.text == f"Practice run {k + 1} of 3"
        skipped.skip(reason="practice not needed")
    screen = skipped.screen()  # straight to the first task run: nothing to rate
    assert screen.phase == "ready" and screen.progress.text == "Run 1 of 8"
    skip_events = [e for e in store.events() if e.kind == "skip"]
    after_training = next(s.index for s in skipped.plan if s.questionnaire == "after_training")
    assert after_training in skip_events[-1].detail["steps"]
    skipped.close()


def test_withdraw_mid_trial(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    run = session.start_trial(input_source=None)
    run.tick()
    screen = session.withdraw(reason="felt unwell")
    assert screen.phase == "done" and session.status == "withdrawn" and run.over
    trial = store.trial(run.trial_id)
    assert (trial.status, trial.outcome, trial.ticks) == ("interrupted", "aborted", 1)
    with pytest.raises(SessionStateError, match="already withdrawn"):
        session.end(reason="x")
    with pytest.raises(SessionStateError, match="cannot agree on the done screen"):
        session.agree()
    session.close()
    with pytest.raises(SessionStateError, match="already withdrawn; there is nothing to resume"):
        Session.reopen(store, protocol, "P01", trial_factory=stub_factory)
    # the withdrawn participant's design row goes to the next enrolment
    nxt = enrol(store, protocol, "P02")
    assert nxt.schedule_row == session.schedule_row
    nxt.close()


def test_schedule_rows_counterbalance_across_participants(store: Store, protocol: Protocol) -> None:
    rows = []
    for i in range(1, 5):
        s = enrol(store, protocol, f"P{i:02d}")
        rows.append(s.schedule_row)
        s.end(reason="testing enrolment only")
        s.close()
    assert rows == [0, 1, 2, 3]
    firsts = {store.assignments(f"P{i:02d}")[0].task for i in range(1, 5)}
    assert len(firsts) == 4  # Latin square: each task first once


def test_participant_id_errors(store: Store, protocol: Protocol) -> None:
    enrol(store, protocol).close()
    with pytest.raises(DuplicateParticipantError, match="P01 is already enrolled"):
        enrol(store, protocol)
    with pytest.raises(UnknownParticipantError, match="P09 is not enrolled"):
        Session.reopen(store, protocol, "P09", trial_factory=stub_factory)
    with pytest.raises(InvalidParticipantIdError):
        enrol(store, protocol, "Ada Lovelace")
    assert [p.participant for p in store.participants()] == ["P01"]


def test_second_session_object_is_refused_until_closed(store: Store, protocol: Protocol) -> None:
    first = enrol(store, protocol)
    with pytest.raises(SessionLockedError, match="already open in this process"):
        Session.reopen(store, protocol, "P01", trial_factory=stub_factory)
    first.close()
    with pytest.raises(SessionClosedError):
        first.start()
    second = Session.reopen(store, protocol, "P01", trial_factory=stub_factory)
    assert second.screen().phase == "waiting"
    second.close()


def test_close_mid_trial_marks_it_interrupted_and_resume_repeats_it(
    store: Store, protocol: Protocol
) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    finish_run(session)
    run = session.start_trial(input_source=None)
    run.tick()
    session.close()
    assert store.trial(run.trial_id).status == "interrupted"
    again = Session.reopen(store, protocol, "P01", trial_factory=stub_factory)
    again.start()
    assert again.screen().progress.text == "Practice run 2 of 3"
    assert again.overview().attempt == 2
    again.close()


def test_other_protocol_is_refused(tmp_path: Path, store: Store, protocol: Protocol) -> None:
    text = PROTOCOL_PATH.read_text().replace('version = "1.0.0"', 'version = "1.0.1"')
    other = parse_protocol(text, path="other.toml")
    assert other.content_hash != protocol.content_hash
    with pytest.raises(ProtocolMismatchError, match=r"not by 'dragan2013' version 1\.0\.1"):
        open_store(store.path, other)
    with pytest.raises(ProtocolMismatchError):
        Session.enrol(store, other, "P01", trial_factory=stub_factory)
    assert store.participants() == []


def test_thread_safety(store: Store, protocol: Protocol) -> None:
    """UI threads read screens and pause/resume while the control thread ticks."""
    session = enrol(store, protocol)
    to_step(session, "ready")
    run = session.start_trial(input_source=None)
    run.trial.n = 400
    errors: list[BaseException] = []
    stop = threading.Event()

    def ui() -> None:
        try:
            while not stop.is_set():
                session.screen()
                session.overview()
                try:
                    session.pause()
                    session.resume()
                except SessionStateError:
                    pass
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=ui) for _ in range(3)]
    for t in threads:
        t.start()
    done = threading.Event()

    def control() -> None:
        run.run_to_end(idle_s=0.0005)
        done.set()

    ctl = threading.Thread(target=control)
    ctl.start()
    assert done.wait(30)
    stop.set()
    for t in [*threads, ctl]:
        t.join()
    assert not errors
    with pytest.raises(SessionStateError, match="second thread"):
        run.tick()
    trial = store.trial(run.trial_id)
    assert trial.status == "completed" and trial.ticks == 400 == store.sample_count(run.trial_id)
    assert session.screen().phase == "ready"
    session.close()


def test_experimenter_overview_carries_the_condition(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    overview = session.overview()
    assert overview.phase == "waiting" and overview.experimenter_actions == (
        "start",
        "withdraw",
        "end",
    )
    to_step(session, "questions", questionnaire="after_training")
    session.answer({"helpful": 4, "matched": 4, "teammate": 4})
    overview = session.overview()
    first = store.assignments("P01")[0]
    task = protocol.task(first.task)
    assert (overview.task, overview.mode, overview.run, overview.attempt) == (
        first.task,
        first.mode,
        "first",
        1,
    )
    assert (overview.difficulty, overview.correctness) == (task.difficulty, task.correctness)
    assert overview.trials_completed == 3 and overview.ratings == 3
    # the step before is the baseline questions, so there is no trial to redo
    assert set(overview.experimenter_actions) == {"pause", "withdraw", "end", "skip"}
    finish_run(session)
    assert "redo" in session.overview().experimenter_actions
    assert len(overview.schedule) == 8
    session.close()


def test_a_failing_listener_does_not_break_the_session(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)

    def broken(screen: object) -> None:
        raise RuntimeError("UI bug")

    session.add_listener(broken)
    assert session.start().phase == "consent"
    assert session.agree().phase == "ready"
    session.close()


def test_lost_lease_stops_writes(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    session.start()
    events = len(store.events())
    with store.transaction() as tx:  # another host's process took the session over
        tx.cur.execute("UPDATE leases SET token = 'other', pid = 1 WHERE participant = 'P01'")
    with pytest.raises(SessionLockedError, match="now held by process 1"):
        session.agree()
    with pytest.raises(SessionLockedError, match="must stop writing"):
        session.record_event("tab_connected", {"client": 3})
    assert session.cursor == 0 and store.session("P01").cursor == 0
    assert len(store.events()) == events


def test_close_after_a_takeover_writes_nothing_and_does_not_raise(
    store: Store, protocol: Protocol
) -> None:
    """A simulator or server closing a session that another process has just taken over (before
    the lease keeper noticed) must not crash on the way out, nor write into the new owner's
    session."""
    session = enrol(store, protocol)
    session.start()
    events = len(store.events())
    with store.transaction() as tx:
        tx.cur.execute("UPDATE leases SET token = 'other', pid = 1 WHERE participant = 'P01'")
    session.close()
    session.close()  # idempotent
    assert len(store.events()) == events
    assert store.session("P01").cursor == 0


def test_end_before_start_and_waiting_screen(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    screen = session.screen()
    assert (
        screen.phase == "waiting"
        and screen.actions == ()
        and screen.progress.text == ""  # no run yet
    )
    with pytest.raises(MissingReasonError, match="end needs a reason"):
        session.end(reason="")
    assert session.end(reason="participant did not show up").phase == "done"
    assert store.session("P01").status == "ended" and store.session("P01").ended_at
    session.close()


def test_a_failed_commit_at_trial_end_is_retried_by_the_next_tick(
    store: Store, protocol: Protocol, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = enrol(store, protocol)
    to_step(session, "ready")
    run = session.start_trial(input_source=None)
    for _ in range(4):
        run.tick()
    real = store.insert_samples

    def disk_full(rows: object) -> None:
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(store, "insert_samples", disk_full)
    with pytest.raises(StoreError, match="disk is full"):
        run.tick()  # the trial's last tick: its samples cannot be committed
    assert session.screen().phase == "running" and not run.over
    assert store.trial(run.trial_id).status == "running"
    monkeypatch.setattr(store, "insert_samples", real)
    assert run.tick() is None and run.over  # retried: samples, then the trial, committed
    trial = store.trial(run.trial_id)
    assert trial.status == "completed" and trial.ticks == 5 == store.sample_count(run.trial_id)
    assert session.screen().progress.text == "Practice run 2 of 3"
    session.close()

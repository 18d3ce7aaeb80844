"""What the participant reads, as a new participant would count and address it: the runs
counted as the consent counts them (practice apart from the main part), the preference naming
the two runs it compares by the numbers the page showed (never by a condition), and the consent
and debrief of a participant who came by the open link (no experimenter to ask). Sessions run
on stub trials (milliseconds)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from study.protocol import Protocol, load_protocol
from study.server.blinding_guard import check_text
from study.server.live.texts import end_screen
from study.session import Screen, Session, open_store
from study.session.answers import ScriptedAnswers
from study.session.headless import run_headless
from tests.protocol_copies import PAPER_PROTOCOL, STUDY_PROTOCOLS
from tests.support.sessions import enrol, stub_factory, to_step

NUMBER_WORDS = {2: "two", 3: "three", 4: "four", 8: "eight", 12: "twelve", 16: "sixteen"}
PID = "5f3c1a2b3c4d5e6f7a8b9c0d"


def _walk(tmp_path: Path, protocol: Protocol, **enrol_kw: Any) -> tuple[Session, list[Screen]]:
    """A whole session on stub trials; every screen the participant was shown, in order."""
    store = open_store(tmp_path / f"{protocol.id}.db", protocol)
    session = enrol(store, protocol, **enrol_kw)
    screens = [session.screen()]
    session.add_listener(screens.append)
    report = run_headless(session, answerer=ScriptedAnswers(seed=4))
    assert report.status == "completed"
    return session, screens


@pytest.mark.parametrize("path", STUDY_PROTOCOLS, ids=lambda p: p.stem)
def test_runs_are_counted_as_the_consent_counts_them(tmp_path: Path, path: Path) -> None:
    protocol = load_protocol(path)
    session, screens = _walk(tmp_path, protocol)
    practice, runs = protocol.training.runs, session.plan.n_runs
    titles = [s.title for s in screens if s.phase == "ready"]
    assert titles == [f"Practice run {k} of {practice}" for k in range(1, practice + 1)] + [
        f"Run {k} of {runs}" for k in range(1, runs + 1)
    ]
    counters = {s.progress.text for s in screens}
    assert not any("Trial" in c for c in counters)
    # the questions after the last practice run count it; the closing ones the last run
    assert {s.progress.text for s in screens if s.questionnaire == "after_training"} == {
        f"Practice run {practice} of {practice}"
    }
    assert screens[-1].phase == "done" and screens[-1].progress.text == f"Run {runs} of {runs}"
    if "practice runs, then" in protocol.texts.consent:  # the consent's promise, kept
        promise = f"{NUMBER_WORDS[practice]} practice runs, then {NUMBER_WORDS[runs]} runs"
        assert promise in " ".join(protocol.texts.consent.split())
    session.close()


@pytest.mark.parametrize("path", STUDY_PROTOCOLS, ids=lambda p: p.stem)
def test_the_preference_names_its_two_runs_by_their_numbers_never_a_condition(
    tmp_path: Path, path: Path
) -> None:
    protocol = load_protocol(path)
    if not protocol.questionnaire.after_task:
        pytest.skip(f"{path.stem} asks no preference")
    session, screens = _walk(tmp_path, protocol)
    words = protocol.condition_words
    asked = []
    for k, screen in enumerate(screens):
        if screen.questionnaire != "after_task" or screen.phase != "questions":
            continue
        titles = [s.title for s in screens[:k] if s.phase == "ready"]
        runs = [int(t.split()[1]) for t in titles if t.startswith("Run ")][-2:]
        asked.append(runs)
        assert f"run {runs[0]} and run {runs[1]}" in screen.text, screen.text
        assert "this task" not in screen.text and "twice" not in screen.text
        check_text(screen.text, words=words)  # the guard's words: no condition name
        check_text(json.dumps(dataclasses.asdict(screen)), words=words)
    assert asked == [[k, k + 1] for k in range(1, session.plan.n_runs, 2)]
    item = protocol.questionnaire.item("preference")
    assert "this task" not in item.prompt
    session.close()


@pytest.mark.parametrize("path", STUDY_PROTOCOLS, ids=lambda p: p.stem)
def test_an_open_link_participant_is_never_told_to_ask_the_experimenter(path: Path) -> None:
    protocol = load_protocol(path)
    online = protocol.texts.for_link()
    for text in (online.consent, online.debrief):
        assert "experimenter" not in text
        check_text(text, words=protocol.condition_words)


def test_the_consent_and_debrief_follow_how_the_participant_came_in(tmp_path: Path) -> None:
    protocol = load_protocol(PAPER_PROTOCOL)
    texts = protocol.texts
    assert "ask the experimenter" in texts.consent and "ask" in texts.debrief
    store = open_store(tmp_path / "s.db", protocol)
    lab = enrol(store, protocol, "P01")
    link = enrol(store, protocol, "L0001", recruitment={"PROLIFIC_PID": PID})
    for session in (lab, link):
        to_step(session, "consent")
    assert lab.screen().text == texts.consent.strip()
    assert link.screen().text == texts.consent_online.strip()
    assert "site where you found this study" in link.screen().text
    link.close()
    link = Session.reopen(
        store, protocol, "L0001", trial_factory=stub_factory
    )  # a restart: still the online texts
    for session in (lab, link):
        to_step(session, "debrief")
    assert lab.screen().text == texts.debrief.strip()
    assert link.screen().text == texts.debrief_online.strip()
    for session in (lab, link):
        session.finish()
    _, lab_end, _ = end_screen("completed", lab.texts)
    _, link_end, _ = end_screen("completed", link.texts)
    assert "ask the experimenter now" in lab_end and "experimenter" not in link_end
    lab.close()
    link.close()

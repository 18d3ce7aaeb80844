"""What the participant reads, as a new participant would count and address it: the runs
counted as the consent counts them (practice apart from the main part), the preference naming
the two runs it compares by the numbers the page showed (never by a condition), the consent
and debrief of a participant who came by the open link (no experimenter to ask), the keys
before the first run, and fields without tooltips over the lines above them.

Sessions run on stub trials (milliseconds); the page checks read the frames a viser server
sends to a bare websocket client."""

from __future__ import annotations

import asyncio
import dataclasses
import json
import time
from pathlib import Path
from typing import Any

import pytest
import viser

from study.protocol import NumberItem, Protocol, load_protocol
from study.server.blinding_guard import check_text
from study.server.live.screens import show_screen
from study.server.live.texts import RUN_FINISHED, end_screen
from study.server.participant_page import KEYS_BEFORE_START, ParticipantPage, message_screen
from study.session import Progress, Screen, Session, open_store
from study.session.answers import ScriptedAnswers
from study.session.headless import run_headless
from tests.browser.harness import run_async
from tests.protocol_copies import PAPER_PROTOCOL, STUDY_PROTOCOLS
from tests.support.raw_client import RawClient, bare_page
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
    # a run's number above the questions about that run, above no others (the practice's
    # questions ask about every practice run; the closing ones about the whole study)
    for s in screens:
        if s.phase != "questions":
            continue
        if s.questionnaire in ("after_run", "after_task"):
            assert s.progress.text.startswith("Run "), (s.questionnaire, s.progress.text)
        else:
            assert s.progress.text == "", (s.questionnaire, s.progress.text)
    assert screens[-1].phase == "done" and screens[-1].progress.text == f"Run {runs} of {runs}"
    if "practice runs, then" in protocol.texts.consent:  # the consent's promise, kept
        promise = f"{NUMBER_WORDS[practice]} practice runs, then {NUMBER_WORDS[runs]} runs"
        assert promise in " ".join(protocol.texts.consent.split())
    session.close()


PREFERENCE_PROTOCOLS = [p for p in STUDY_PROTOCOLS if load_protocol(p).questionnaire.after_task]
"""The shipped protocols that ask which of a task's two runs was preferred."""


@pytest.mark.parametrize("path", PREFERENCE_PROTOCOLS, ids=lambda p: p.stem)
def test_the_preference_names_its_two_runs_by_their_numbers_never_a_condition(
    tmp_path: Path, path: Path
) -> None:
    protocol = load_protocol(path)
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


# -- the page's frames -------------------------------------------------------------------------
class _Handlers:
    """The session's side of the buttons: nothing happens."""

    def __getattr__(self, name: str) -> Any:
        return lambda *a, **k: None


def _frames(build: Any) -> list[dict[str, Any]]:
    """The messages a tab receives while ``build(page)`` draws a screen on a fresh page."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    words = load_protocol(PAPER_PROTOCOL).condition_words

    async def run() -> list[dict[str, Any]]:
        async with RawClient(server.get_port()) as tab:
            page = await bare_page(server, words=words)
            await asyncio.get_running_loop().run_in_executor(None, build, page)
            seen, quiet_since = -1, time.monotonic()  # until nothing new for 0.5 s (under
            while time.monotonic() - quiet_since < 0.5:  # load a fixed 0.5 s missed some)
                if len(tab.messages) != seen:
                    seen, quiet_since = len(tab.messages), time.monotonic()
                await asyncio.sleep(0.05)
            return list(tab.messages)

    try:
        return run_async(run())
    finally:
        server.stop()


def _added(messages: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    """The elements of ``kind`` the tab was sent, but the page's hidden ones (the keys)."""
    return [
        m
        for m in messages
        if m.get("type") == kind and m.get("props", {}).get("visible", True) is not False
    ]


def _markdown(messages: list[dict[str, Any]]) -> str:
    return "\n".join(str(m["props"]["_markdown"]) for m in _added(messages, "GuiMarkdownMessage"))


def test_the_keys_are_on_the_start_screen_and_the_run_counted_once() -> None:
    screen = Screen(
        phase="ready",
        title="Practice run 1 of 3",
        text="Practice run: pick up the mug.",
        progress=Progress(1, 3, practice=True),
        actions=("start_trial",),
    )
    messages = _frames(
        lambda page: show_screen(
            page,
            screen,
            fault=False,
            paused_by=None,
            outcome=None,
            agree_label="I agree",
            handlers=_Handlers(),  # type: ignore[arg-type]
        )
    )
    shown = _markdown(messages)
    assert KEYS_BEFORE_START in shown and "**W**/**S**" in shown and "**G**" in shown
    assert shown.count("Practice run 1 of 3") == 1 and "Trial" not in shown
    labels = [m["props"]["label"] for m in _added(messages, "GuiButtonMessage")]
    assert labels == ["Start"]


def test_the_join_code_field_has_no_tooltip_over_the_error() -> None:
    notice = "That code did not work. Please check it with the experimenter and type it again."
    messages = _frames(lambda page: page.show_join(ask_code=True, on_code=print, notice=notice))
    (field,) = _added(messages, "GuiTextMessage")
    assert not field["props"].get("hint")
    shown = _markdown(messages)
    assert notice in shown and "six letters and digits" in shown


def test_a_number_out_of_range_is_said_once() -> None:
    protocol = load_protocol(PAPER_PROTOCOL)
    item = protocol.questionnaire.item("game_hours")
    assert isinstance(item, NumberItem)
    messages = _frames(
        lambda page: page.show_questions(
            "Questions", "About you.", [item], progress=None, on_submit=print
        )
    )
    (field,) = _added(messages, "GuiTextMessage")
    assert not field["props"].get("hint")
    accepts = f"Please enter {item.range_text()}."
    assert _markdown(messages).count(accepts) == 1  # the line under the field, once


def test_a_runs_outcome_goes_with_the_screen_that_says_it() -> None:
    """h11: the blue "You lifted the box." stayed its 6 s over the questions after Continue,
    and over the next run's Start screen in 4 of 8 task runs. It stays while the "Run finished"
    screen shows (its own, shown again included) and goes with the next screen."""

    def build(page: ParticipantPage) -> None:
        page.notify("You lifted the box.", seconds=6.0, screen=message_screen(RUN_FINISHED))
        page.show_message(RUN_FINISHED, "You lifted the box.", button="Continue", on_button=int)
        page.show_message(RUN_FINISHED, "You lifted the box.", button="Continue", on_button=int)
        time.sleep(0.5)  # on the tab (sent before it is taken down, not coalesced away)
        page.notify("Time is running out.")  # a notice of no screen: closes by itself only
        page.show_message("Questions", "How helpful was the robot?")

    messages = _frames(build)
    shown = [m["uuid"] for m in messages if m.get("type") == "NotificationShowMessage"]
    removed = [m["uuid"] for m in messages if m.get("type") == "RemoveNotificationMessage"]
    assert len(shown) == 2 and removed == shown[:1]
    kinds = [m.get("type") for m in messages]
    markdown = [k for k, m in enumerate(messages) if "Questions" in str(m.get("props", {}))]
    assert kinds.index("RemoveNotificationMessage") < markdown[0]  # before the questions show

"""The questions asked once per participant, in headless Chromium, checked against the store.

With the shipped protocol's demographics, attention check, closing comment and data-retention
question: a participant picks options from dropdowns, types a number out of range (and sees
what the field accepts, Continue held) and then a good one, writes a comment with the words of
a condition in it and one too long (a count, Continue held), shortens it, and declines to have
their data kept. The experimenter skips the runs in between from the console's actions. The
store holds every answer as given; no frame to the page carries a condition word, the comment
included, and the blinding guard records no leak for what the participant typed. The export
leaves the participant out and says why.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import expect

from study.export import tidy_tables
from tests.browser.harness import FrameLog, RunningServer, start_server, wait_until
from tests.browser.page import AGREE, connect_page, join, screenshot

pytestmark = pytest.mark.browser

COMMENT = "The arm went right for the bottle; hard to steer when it was wrong. "


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(tmp_path, time_limit_s=30.0, training_runs=1, asked_once=True)
    try:
        yield rs
    finally:
        rs.stop()


def _field(page: Any, n: int) -> Any:
    """The ``n``-th text field of the panel (number and free-text answers), in page order."""
    return page.locator(".mantine-TextInput-input:visible, textarea:visible").nth(n)


def _choose(page: Any, k: int, option: str) -> None:
    """Open the ``k``-th dropdown and click ``option``."""
    box = page.locator(".mantine-Select-input:visible").nth(k)
    box.click()
    page.get_by_role("option", name=option, exact=True).click()
    expect(box).to_have_value(option)


def _skip_to(rs: RunningServer, code: str, questionnaire: str) -> None:
    """The experimenter skips each run and its questions until ``questionnaire`` is asked (the
    attention check between tasks and the closing questions are left to the participant)."""
    live = rs.server.session(code)
    for _ in range(60):
        screen = live.session.screen()
        if screen.phase == "questions" and screen.questionnaire == questionnaire:
            return
        rs.server.act(code, "skip", reason="test: straight to the closing questions")
    raise AssertionError("never reached the closing questions")


def test_demographics_attention_comment_and_retention(
    study: RunningServer, context: Any, screenshots: Path
) -> None:
    srv, store = study.server, study.store
    words = study.protocol.condition_words
    page = context.new_page()
    frames = FrameLog().attach(page)
    connect_page(page, study.url)
    code = srv.enrol("P01")
    join(page, code, then=None)
    srv.act(code, "start")
    page.get_by_role("button", name=AGREE).click()

    # About you: four dropdowns (nothing preselected) and the hours of gaming.
    page.get_by_text("How old are you?").wait_for()
    cont = page.get_by_role("button", name="Continue")
    expect(cont).to_be_disabled()
    for k, option in enumerate(("25-34", "Prefer not to say", "With either hand equally", "None")):
        _choose(page, k, option)
    expect(cont).to_be_disabled()  # the hours are still missing
    hours = _field(page, 0)
    hours.click()
    page.keyboard.type("250", delay=30)
    page.get_by_text("Please enter a number from 0 to 100 (hours per week).").first.wait_for()
    expect(cont).to_be_disabled()
    hours.fill("")
    page.keyboard.type("7,5", delay=30)
    page.get_by_text("Your answer: 7.5 hours per week").wait_for()
    screenshot(page, screenshots, "05a-about-you")
    expect(cont).to_be_enabled()
    cont.click()
    page.get_by_role("button", name="Start").wait_for()
    got = {a.item: (a.value, a.number) for a in store.answers(participant="P01")}
    assert got == {
        "age_band": ("25-34", None),
        "gender": ("Prefer not to say", None),
        "handedness": ("With either hand equally", None),
        "robot_experience": ("None", None),
        "game_hours": ("7.5", 7.5),
    }

    # The attention check after the second task (the runs skipped by the experimenter).
    _skip_to(study, code, "between_tasks")
    page.get_by_text("please choose Somewhat").wait_for()
    _choose(page, 0, "Very much")  # a lapse: recorded as given
    page.get_by_role("button", name="Continue").click()
    # The experimenter acts only once the answer has landed (a skip sent while the page's
    # Continue is still on its way would skip the questions the participant just answered).
    assert wait_until(lambda: any(a.item == "attention" for a in store.answers(participant="P01")))

    # Closing: a comment naming conditions, first too long, then shortened; then "No".
    _skip_to(study, code, "closing")
    page.get_by_text("anything else you would like to tell us").wait_for()
    cont = page.get_by_role("button", name="Continue")
    comment = _field(page, 0)
    comment.click()
    comment.fill(COMMENT * 16)  # 1,072 characters
    page.get_by_text("of 1000 characters: please shorten it").wait_for()
    _choose(page, 0, "No, please do not use my data")
    expect(cont).to_be_disabled()
    comment.fill(COMMENT * 2)
    page.get_by_text(f"{len((COMMENT * 2).strip())} of 1000 characters.").wait_for()
    screenshot(page, screenshots, "05b-closing")
    expect(cont).to_be_enabled()
    cont.click()
    page.get_by_role("button", name="Finish").wait_for()

    answers = {a.item: a for a in store.answers(participant="P01")}
    assert answers["attention"].value == "Very much" and answers["attention"].kind == "attention"
    assert answers["comment"].value == (COMMENT * 2).strip()  # data, kept as typed
    assert answers["keep_data"].value == "No, please do not use my data"
    guard = srv.guard
    assert guard.blocked == 0 and guard.redacted == 0, guard.violations
    assert guard.echoes > 0  # the typing's own echoes, dropped unread
    raw = frames.raw_bytes()
    for word in words:
        assert word.encode() not in raw, f"{word!r} reached the participant's page"
    assert b"the arm went" not in raw  # the comment never went back to the page

    # The participant declined: export leaves them out and says why.
    assert wait_until(lambda: store.answers(participant="P01") is not None)
    tables = tidy_tables(store)
    assert tables["trials"].empty and tables["answers"].empty
    row = tables["participants"].set_index("participant").loc["P01"]
    assert not row["included"] and "declined" in row["excluded_because"]

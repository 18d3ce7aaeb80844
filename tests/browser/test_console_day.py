"""The experimenter's console over two participants, used in a browser as an experimenter would.

P01 is enrolled from the console (the ID field clears), joins in a real tab and consents; the
console's Start is the only action enabled before the start; the practice run and a task run
end by themselves (timeouts), the tab is reloaded once, the experimenter pauses and resumes,
a redo with an empty reason is refused and one with a reason goes through. The timeline at the
top shows each of these with its time, the study's progress shows the task run's condition and
the next participant's schedule row. P02 is enrolled next: selecting it shows none of P01's
plot, reason or result, and ending it asks for a reason and confirmation, says it is final, and
then leaves only nothing to do. Screenshots of the console are read by the developer.
"""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import expect

from study.server.live import session_factory
from study.server.server import StudyServer
from tests.browser.harness import RunningServer, start_server, wait_until
from tests.browser.page import AGREE, connect_page, join, screenshot, text_input, wait_connected
from tests.protocol_copies import short_practice

pytestmark = pytest.mark.browser

TIME_LIMIT_S = 30.0
"""Long enough for the console's Pause to land mid-run on a busy machine (a click on it took
1.4-2 s here at load 14, and over 10 s in one CI run); the rest of the run is waited out."""
PRACTICE_S = 3.0
"""The practice run, only waited out."""
ACTIONS = ("Start", "Pause", "Resume", "Redo", "Skip", "Withdraw", "End")


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(
        tmp_path,
        time_limit_s=TIME_LIMIT_S,
        training_runs=1,
        edit=lambda p: short_practice(p, seconds=PRACTICE_S),
    )
    try:
        yield rs
    finally:
        rs.stop()


def _enabled(console: Any) -> set[str]:
    return {a for a in ACTIONS if console.get_by_role("button", name=a, exact=True).is_enabled()}


def _wait_enabled(console: Any, expected: set[str]) -> None:
    assert wait_until(lambda: _enabled(console) == expected, timeout=15), _enabled(console)


def _enrol(console: Any, pid: str) -> str:
    field = text_input(console, "Participant ID")
    field.fill(pid)
    console.get_by_role("button", name="Enrol and open session").click()
    status = console.get_by_text(re.compile(rf"Session for {pid}: join code"))
    status.wait_for()
    expect(field).to_have_value("")  # ready for the next participant's ID
    return re.search(r"code ([A-Z0-9]{6})", status.inner_text()).group(1)  # type: ignore[union-attr]


def _timeline(console: Any) -> str:
    return console.locator("table").filter(has_text="what").first.inner_text()


def body_text(page: Any) -> str:
    return page.locator("body").inner_text()


CONFIDENCE_RGB = (0x19, 0x71, 0xC2)


def _drawn(console: Any) -> bool:
    """Whether the arbitration plot shows its confidence line (pixels of its colour)."""
    png = console.locator(".uplot").first.screenshot()
    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    near = np.abs(rgb - np.array(CONFIDENCE_RGB)).sum(axis=2) < 40
    return int(near.sum()) > 300  # the legend's marker alone has about 45


def _progress(console: Any) -> str:
    tables = console.locator("table").filter(has_text="condition")
    return tables.first.inner_text() if tables.count() else ""


def test_a_day_of_two_sessions_from_the_console(
    study: RunningServer, context: Any, screenshots: Path
) -> None:
    srv, store = study.server, study.store
    console = context.new_page()
    console.set_viewport_size({"width": 1366, "height": 1400})
    connect_page(console, study.console_url)
    console.get_by_text("Participants completed: 0").wait_for()

    code1 = _enrol(console, "P01")
    _wait_enabled(console, {"Start", "Withdraw", "End"})  # nothing else before the start
    console.get_by_text("Session time not started").wait_for()

    page = context.new_page()
    connect_page(page, study.url)
    join(page, code1, then=None)
    console.get_by_role("button", name="Start", exact=True).click()
    page.get_by_role("button", name=AGREE).click()
    _wait_enabled(console, {"Pause", "Skip", "Withdraw", "End"})
    assert "session started" in _timeline(console) and "consent given" in _timeline(console)
    assert wait_until(lambda: re.search(r"Session time 00:\d\d", body_text(console)))

    # the practice run times out by itself; the outcome, a reload and the questions
    page.get_by_role("button", name="Start").click()
    console.get_by_text("Arbitration").wait_for()
    assert wait_until(
        lambda: re.search(r"run 1: practice, unassisted -> timeout", _timeline(console))
    )
    page.get_by_role("button", name="Continue").click()  # "Run finished"
    page.reload()
    wait_connected(page)
    assert wait_until(lambda: "tab reconnected (reload)" in _timeline(console))
    live = srv.session(code1)
    assert wait_until(lambda: live.session.screen().phase == "questions")
    live.answer({i.id: 4 for i in live.session.screen().items})

    # a task run: paused and resumed from the console mid-run, then it times out
    page.get_by_role("button", name="Start").click()
    assert wait_until(lambda: live.run is not None and not live.run.over)
    console.get_by_role("button", name="Pause", exact=True).click()
    _wait_enabled(console, {"Resume", "Redo", "Skip", "Withdraw", "End"})
    assert "(paused)" in console.locator("body").inner_text()
    assert not live.run.over, _timeline(console)  # paused mid-run: the run waits
    line = re.search(r"Condition: .*", body_text(console))
    assert line is not None and re.fullmatch(
        r"Condition: task: \S+ \(\w+, \w+\), mode \w+, first run, attempt 1", line[0]
    ), line
    screenshot(console, screenshots, "console-01-paused")
    console.get_by_role("button", name="Resume", exact=True).click()
    assert wait_until(lambda: "resumed" in _timeline(console))
    assert wait_until(lambda: "Run finished" in body_text(page), timeout=3 * TIME_LIMIT_S)
    first_task = next(t for t in store.trials(participant="P01") if t.phase == "task")
    assert wait_until(
        lambda: re.search(rf"run 2: {first_task.task} .*-> timeout", _timeline(console))
    )
    condition = f"{first_task.difficulty}/{first_task.correctness}, {first_task.mode}"
    assert wait_until(lambda: f"{condition}\t1\t0/1 (0%)" in _progress(console), timeout=10)

    # redo needs a reason: an empty one is refused, nothing changes
    console.get_by_role("button", name="Redo", exact=True).click()
    console.get_by_role("button", name="Confirm redo").click()
    console.get_by_text("Redo needs a reason").wait_for()
    assert [t.status for t in store.trials(participant="P01")].count("redone") == 0
    text_input(console, "Reason").fill("participant sneezed")
    console.get_by_role("button", name="Confirm redo").click()
    assert wait_until(lambda: "redo: participant sneezed" in _timeline(console))
    assert [t.status for t in store.trials(participant="P01")].count("redone") == 1
    body = console.locator("body").inner_text()
    assert "attempt None" not in body and "attempt 2" in body
    assert wait_until(
        lambda: condition not in _progress(console), timeout=10
    )  # redone: not counted
    console.get_by_text(re.compile(r"Next participant: schedule row 1")).wait_for()
    screenshot(console, screenshots, "console-02-redo")

    # the second participant: nothing of P01 shows, and End is final and asks first
    assert wait_until(lambda: srv.console.plotted)  # P01's last run
    assert srv.console.alpha_plot.data[0].size > 100
    assert wait_until(lambda: _drawn(console), timeout=20, interval=1.0)  # and it is drawn
    code2 = _enrol(console, "P02")
    assert wait_until(lambda: f"P02 (code {code2})" in body_text(console))
    assert console.get_by_role("combobox").first.input_value() == f"P02 ({code2})"
    body = console.locator("body").inner_text()
    assert "participant sneezed" not in body and "Redo needs" not in body
    assert "P01 (code" not in body and "Control error" not in body
    assert srv.session(code2).plots.arrays()[1].size == 0
    assert not srv.console.plotted and srv.console.prob_plot is None
    assert np.isnan(srv.console.alpha_plot.data[1]).all()
    _wait_enabled(console, {"Start", "Withdraw", "End"})
    console.get_by_role("button", name="End", exact=True).click()
    console.get_by_text("cannot be continued").wait_for()
    console.get_by_role("button", name="Confirm end").click()
    console.get_by_text("End needs a reason").wait_for()
    assert store.session("P02").status == "enrolled"
    text_input(console, "Reason").fill("no-show: did not arrive")
    console.get_by_role("button", name="Confirm end").click()
    assert wait_until(lambda: store.session("P02").status == "ended")
    _wait_enabled(console, set())
    assert wait_until(lambda: "ended: no-show: did not arrive" in _timeline(console))
    console.get_by_text(re.compile(r"withdrawn or ended 1")).wait_for()

    # the open link, from the console: places first, then on
    console.get_by_text("Open link", exact=True).click()
    places = text_input(console, "Places")
    places.fill("3")
    places.press("Enter")
    console.get_by_text("Open link on").click()
    assert wait_until(lambda: srv.link().enabled and srv.link().cap == 3)
    console.get_by_text("0 of 3 places taken").wait_for()
    assert "PROLIFIC_PID={{%PROLIFIC_PID%}}" in body_text(console)
    assert "Condition: none: the session is ended" in body_text(console)
    screenshot(console, screenshots, "console-03-ended")

    # the server goes down; a new one on the same store offers P01's session for reopening
    srv.stop()
    again = StudyServer(
        session_factory(store, study.protocol),
        condition_words=study.protocol.condition_words,
        host="127.0.0.1",
        port=0,
        experimenter_port=0,
    )
    try:
        fresh = context.new_page()
        fresh.set_viewport_size({"width": 1366, "height": 1400})
        connect_page(fresh, f"http://127.0.0.1:{again.experimenter_port}")
        reopen = fresh.get_by_role("button", name="Reopen session")
        expect(reopen).to_be_enabled()
        fresh.get_by_role("combobox").nth(1).click()  # the "Interrupted" list
        fresh.get_by_role("option", name="P01").click()
        reopen.click()
        fresh.get_by_text(re.compile(r"Reopened P01: join code")).wait_for()
        assert "session reopened" in _timeline(fresh)
        assert wait_until(lambda: "run 2: " in _timeline(fresh))  # the earlier runs are there
        _wait_enabled(fresh, {"Start", "Withdraw", "End"})
        expect(reopen).to_be_disabled()  # nothing else left to reopen
    finally:
        again.stop()

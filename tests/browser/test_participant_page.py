"""The participant page's frictions (issue 21), tried as a new participant would at 1366 x 768.

* Enter in the join field joins, as in any form;
* viser's own "Software WebGL rendering detected" notice never shows, on load or after a reload
  (the page is polled from its first moments; headless Chromium draws in software, so viser
  raises the notice every time);
* the panel cannot be minimised: no minimise control, and a click on its header leaves the
  instructions and the study's buttons in place;
* after the practice runs the items speak of the practice runs, not of "the run you just
  finished", and the answer chosen is drawn filled;
* when the experimenter skips every practice run, no practice items are asked.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import expect

from study.server.page_script import HIDDEN_NOTICES
from tests.browser.harness import start_server, wait_until
from tests.browser.page import AGREE, connect_page, screenshot, text_input

pytestmark = pytest.mark.browser

NOTICE = "Software WebGL rendering detected"
FILLED = """() => [...document.querySelectorAll('button')]
  .map(b => [b.textContent.trim(), getComputedStyle(b).backgroundColor])"""
HEADER = """() => {
  const el = [...document.querySelectorAll('span, div, p')].find(e =>
    e.children.length === 0 && e.textContent.trim() === 'Robot arm study' && !e.closest('h3'));
  const r = el.getBoundingClientRect();
  return {x: r.x + r.width / 2, y: r.y + r.height / 2};
}"""


def _no_viewer_notice(page: Any, *, seconds: float = 3.0) -> None:
    """Poll the page from now for ``seconds``: viser's notice is in the page (it was raised)
    but never visible."""
    raised = False
    for _ in range(int(seconds / 0.1)):
        notice = page.locator(f"#{HIDDEN_NOTICES[0]}")
        if notice.count():
            raised = True
            assert not notice.first.is_visible(), "viser's own notice is visible"
        assert not page.get_by_text(NOTICE).first.is_visible()
        page.wait_for_timeout(100)
    assert raised, "the notice was never raised: the check checks nothing"


def _join_with_enter(page: Any, code: str) -> None:
    page.get_by_text("Please type the join code").wait_for()
    field = text_input(page, "Join code")
    field.click()
    page.keyboard.type(code.lower(), delay=40)
    page.keyboard.press("Enter")


def test_enter_joins_no_viewer_notice_panel_stays_and_practice_items_fit(
    tmp_path: Path, wide: Any, screenshots: Path
) -> None:
    rs = start_server(tmp_path, time_limit_s=3.0, training_runs=1)
    try:
        srv = rs.server
        page = wide.new_page()
        page.goto(rs.url)
        _no_viewer_notice(page)
        code = srv.enrol("P01")
        srv.act(code, "start")
        _join_with_enter(page, code)
        page.get_by_role("button", name=AGREE).wait_for()  # Enter joined
        live = srv.session(code)
        assert live.page is not None

        # The panel stays: no minimise control, and a click on its header changes nothing.
        assert page.get_by_label("Minimize panel").count() in (0, 1)
        assert not page.get_by_label("Minimize panel").first.is_visible()
        header = page.evaluate(HEADER)  # the panel's title bar, not the page's heading
        page.mouse.click(header["x"], header["y"])
        page.wait_for_timeout(500)
        expect(page.get_by_role("button", name=AGREE)).to_be_visible()
        assert not page.get_by_label("Expand panel").first.is_visible()

        # A reload: still no viewer notice; the tab rejoins by itself.
        page.reload()
        _no_viewer_notice(page)
        page.get_by_role("button", name=AGREE).click()

        # The practice run times out; its items speak of the practice runs.
        page.get_by_role("button", name="Start").click()
        page.get_by_text("Run finished").wait_for(timeout=30_000)
        page.get_by_role("button", name="Continue").click()
        page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
        body = page.inner_text("body")
        assert rs.protocol.texts.instructions["after_training"].strip() in body
        assert "the run you just finished" not in body

        # The chosen answer is drawn filled; the other points are not.
        page.get_by_role("button", name="5", exact=True).first.click()
        page.get_by_text("Your answer: 5").first.wait_for()
        chosen = page.get_by_role("button", name="[5]", exact=True)
        expect(chosen).to_have_count(1)
        assert wait_until(lambda: chosen.get_attribute("data-study-chosen") is not None, timeout=5)
        colours = dict(page.evaluate(FILLED))
        assert colours["[5]"] != colours["4"], colours
        assert colours["4"] == colours["6"], colours
        screenshot(page, screenshots, "15-practice-items-chosen")
        page.get_by_role("button", name="3", exact=True).nth(1).click()  # the next row
        page.get_by_text("Your answer: 3").first.wait_for()
        marked = page.locator("button[data-study-chosen]").all_inner_texts()
        assert sorted(t.strip() for t in marked) == ["[3]", "[5]"], marked  # one per row

        # A participant whose practice runs are all skipped is not asked about them.
        other = wide.new_page()
        connect_page(other, rs.url)
        code2 = srv.enrol("P02")
        srv.act(code2, "start")
        _join_with_enter(other, code2)
        other.get_by_role("button", name=AGREE).click()
        other.get_by_role("button", name="Start").wait_for()
        srv.act(code2, "skip", reason="knows the task")
        other.get_by_text("Run 1 of 8").first.wait_for()  # the main part: its first run
        other.get_by_role("button", name="Start").wait_for()
        assert "Your answer" not in other.inner_text("body")
        assert srv.session(code2).session.screen().phase == "ready"
    finally:
        rs.stop()

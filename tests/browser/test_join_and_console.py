"""Enrolling from the experimenter's console, and joining with a code when several run.

The experimenter enrols a participant in the console (the join code appears there) and starts
the session with the console's Start; with two sessions open the participant's page asks for
the code, binds to that session, and after a reload binds to it again with the code the
tab kept (a fresh browser must type it).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from tests.browser.harness import RunningServer, start_server, wait_until
from tests.browser.page import AGREE, connect_page, join, screenshot, text_input, wait_connected

pytestmark = pytest.mark.browser


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(tmp_path)
    try:
        yield rs
    finally:
        rs.stop()


def test_console_enrols_and_participant_joins_by_code(
    study: RunningServer, context: Any, screenshots: Path
) -> None:
    srv = study.server
    console = context.new_page()
    connect_page(console, study.console_url)
    text_input(console, "Participant ID").fill("P01")
    console.get_by_role("button", name="Enrol and open session").click()
    status = console.get_by_text(re.compile(r"Session for P01: join code"))
    status.wait_for()
    code = re.search(r"code ([A-Z0-9]{6})", status.inner_text()).group(1)  # type: ignore[union-attr]
    assert srv.session(code).participant == "P01"
    assert study.store.session("P01").status == "enrolled"
    console.get_by_role("button", name="Start", exact=True).click()
    assert wait_until(lambda: study.store.session("P01").status == "running")

    other = srv.enrol("P02")
    srv.act(other, "start")

    page = context.new_page()
    connect_page(page, study.url)
    text_input(page, "Join code").wait_for()
    screenshot(page, screenshots, "00-join-code")
    join(page, "ACDEFH" if code != "ACDEFH" else "HFEDCA", then=None)  # no such code
    page.get_by_text("That code did not work").wait_for()
    join(page, code)
    assert srv.session(code).page is not None and srv.session(other).page is None

    page.reload()  # the tab kept its code: straight back into the session
    wait_connected(page)
    page.get_by_role("button", name=AGREE).wait_for()
    assert wait_until(lambda: srv.session(code).page is not None)
    kinds = [e.kind for e in study.store.events()]
    assert kinds.count("participant_connected") == 2
    assert "participant_disconnected" in kinds

"""The open-enrolment link of an online study, in Chromium as participants from a panel use it.

The server runs with the link on and two places, and a protocol with a completion code and a
redirect back to the panel. A participant opens the Prolific-style link: no join code, the
session starts by itself, the recruitment IDs are stored with the enrolment. A second tab with
the same ID is told the study is open elsewhere and does not take the session over; a reload
rejoins. A generic ``pid`` that holds a condition word gets a session, and no frame the page
receives carries that word. A third ID finds the places taken; a link whose placeholder was
never filled in is refused. At the end the page shows the completion code and goes back to the
panel with the participant's ID filled in by the browser; opening the link again shows the
code again.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from study.server.blinding_guard import iter_strings
from tests.browser.harness import FrameLog, RunningServer, start_server, wait_until
from tests.browser.page import AGREE, connect_page, screenshot
from tests.protocol_copies import with_completion

pytestmark = pytest.mark.browser

PID = "5f3c1a2b3c4d5e6f7a8b9c0d"
STUDY = "60aa11bb22cc33dd44ee55ff"
PANEL = "https://panel.example.org/complete"
REDIRECT = PANEL + "?cc=C0DE1234&who={PROLIFIC_PID}"


@pytest.fixture
def online(tmp_path: Path) -> Any:
    rs = start_server(
        tmp_path,
        time_limit_s=6.0,
        training_runs=1,
        edit=lambda p: with_completion(p, code="C0DE1234", redirect_url=REDIRECT),
        server_kw={"open_link": 2},
    )
    try:
        yield rs
    finally:
        rs.stop()


def _link(rs: RunningServer, query: str) -> str:
    return f"{rs.url}/?{query}"


def _body(page: Any) -> str:
    return page.locator("body").inner_text()


def test_participants_from_a_panel_join_by_the_open_link(
    online: RunningServer, context: Any, screenshots: Path
) -> None:
    srv, store = online.server, online.store
    prolific = f"PROLIFIC_PID={PID}&STUDY_ID={STUDY}&SESSION_ID=abc123"
    first = context.new_page()
    frames = FrameLog().attach(first)
    connect_page(first, _link(online, prolific))
    first.get_by_role("button", name=AGREE).wait_for()  # no join code, started by itself
    assert "join code" not in _body(first)
    # the online consent: nobody beside them to ask (the lab's says "ask the experimenter")
    assert "experimenter" not in _body(first) and "site where you found this study" in _body(first)
    assert store.session("L0001").status == "running"
    enrol = next(e for e in store.events(participant="L0001") if e.kind == "enrol")
    assert enrol.detail["recruitment"] == {
        "PROLIFIC_PID": PID,
        "STUDY_ID": STUDY,
        "SESSION_ID": "abc123",
    }
    live = next(s for s in srv.sessions() if s.participant == "L0001")

    second = context.new_page()  # the same ID in another tab: told, not taken over
    connect_page(second, _link(online, prolific))
    second.get_by_text("already open in another tab").wait_for()
    screenshot(second, screenshots, "link-01-second-tab")
    assert live.page is not None and live.page.client is not None
    held_by = live.page.client.client_id
    second.wait_for_timeout(1500)
    assert live.page is not None and live.page.client.client_id == held_by
    assert "second_tab_refused" in [e.kind for e in store.events(participant="L0001")]
    second.close()

    first.reload()  # a reload with the same ID rejoins
    first.get_by_role("button", name=AGREE).wait_for()
    assert wait_until(lambda: live.page is not None and live.page.client.client_id != held_by)

    marked = context.new_page()  # a generic pid holding a condition word
    marked_frames = FrameLog().attach(marked)
    connect_page(marked, _link(online, "pid=timid42"))
    marked.get_by_role("button", name=AGREE).wait_for()
    assert store.session("L0002").status == "running"

    full = context.new_page()
    connect_page(full, _link(online, "PROLIFIC_PID=aaaaaaaaaaaaaaaaaaaaaaaa"))
    full.get_by_text("not taking new participants").wait_for()
    assert not store.has_participant("L0003")
    unfilled = context.new_page()
    connect_page(unfilled, _link(online, "PROLIFIC_PID={{%PROLIFIC_PID%}}"))
    unfilled.get_by_text("This link is missing").wait_for()
    assert srv.link().used == 2

    # the end: completion code, and back to the panel with the ID filled in by the browser
    first.get_by_role("button", name=AGREE).click()
    assert wait_until(lambda: live.session.phase() == "ready")
    while live.session.phase() != "debrief":
        live.act("skip", reason="test: straight to the end")
    visited: list[str] = []

    def panel(route: Any) -> None:
        visited.append(route.request.url)
        route.fulfill(status=200, content_type="text/html", body="<p>Submission received</p>")

    context.route("https://panel.example.org/**", panel)
    first.get_by_role("button", name="Finish").click()
    first.get_by_text("Your completion code is C0DE1234").wait_for()
    assert "experimenter" not in _body(first)  # the online debrief
    screenshot(first, screenshots, "link-02-completion-code")
    first.get_by_text("Submission received").wait_for(timeout=30_000)  # by itself, in 8 s
    assert visited == [f"{PANEL}?cc=C0DE1234&who={PID}"]
    assert store.session("L0001").status == "completed"

    again = context.new_page()  # the link once more: the code again, no new session
    connect_page(again, _link(online, prolific))
    again.get_by_text("Your completion code is C0DE1234").wait_for()
    assert "experimenter" not in _body(again)
    assert [p.participant for p in store.participants()] == ["L0001", "L0002"]

    for log in (frames, marked_frames):
        strings = [s for m in log.messages() for s in iter_strings(m)]
        assert len(strings) > 50
        for word in online.protocol.condition_words:
            assert not [s for s in strings if word in s.lower()], f"{word!r} in a frame"
        assert PID not in " ".join(strings) and "timid42" not in " ".join(strings)
    assert srv.guard.violations == []

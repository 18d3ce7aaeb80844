"""Blinding in the browser, on every shipped study protocol: no frame the page receives names a
condition of the protocol being served.

A participant joins, agrees, does the practice run and one task run (2 s each), answers the
items and finishes, once per protocol (the paper's and memory3, whose levels "standard",
"amnesic", "memory", "oracle" and "linear" are not the paper's words). Every websocket frame
the page receives is decoded and searched, strings and raw bytes (meshes included), for every
word of :attr:`study.protocol.Protocol.condition_words` (a word that is also one of viser's fixed
settings, as memory3's "standard" is a mesh material, is allowed only as that setting); the guard must never have had to
block anything (our code sends no condition word), and the page's visible text is checked too.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import expect

from study.server.blinding_guard import iter_strings
from study.server.viser_vocabulary import FIELD_VALUES
from tests.browser.harness import FrameLog, start_server, wait_until
from tests.browser.page import connect_page, join, without_client_warning
from tests.protocol_copies import PAGE_BLINDED_PROTOCOLS

pytestmark = pytest.mark.browser

TIME_LIMIT_S = 2.0
"""Each run is waited out: long enough for the trial screen to be seen and read."""


def _answer_items(page: Any) -> None:
    """Answer every row of an items screen with its first point, then Continue."""
    none_yet = page.get_by_text("Your answer: none yet")
    ones = page.get_by_role("button", name="1", exact=True)  # one in each unanswered row
    none_yet.first.wait_for(timeout=30_000)
    while left := none_yet.count():
        ones.first.click()
        # awaited, with time for a loaded machine (expect's own default is 5 s: a run beside
        # a busy suite once took longer)
        expect(none_yet).to_have_count(left - 1, timeout=30_000)  # the answer shown
        # and marked "[1]" on its row (a second update, which a loaded page can draw a frame
        # later): only then is the first "1" the next row's, not this one's again
        expect(ones).to_have_count(left - 1, timeout=30_000)
    page.get_by_role("button", name="Continue").click()


def _run_once(page: Any, seen: list[str]) -> None:
    """Ready -> trial (times out) -> outcome -> items."""
    page.get_by_role("button", name="Start").wait_for()
    seen.append(page.inner_text("body"))
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    seen.append(page.inner_text("body"))
    page.get_by_text("Run finished").wait_for(timeout=60_000)
    seen.append(page.inner_text("body"))
    page.get_by_role("button", name="Continue").click()
    _answer_items(page)


@pytest.mark.parametrize("source", PAGE_BLINDED_PROTOCOLS, ids=lambda p: p.stem)
def test_no_frame_names_a_condition_of_the_served_protocol(
    tmp_path: Path, small: Any, source: Path
) -> None:
    rs = start_server(tmp_path, time_limit_s=TIME_LIMIT_S, training_runs=1, source=source)
    try:
        srv = rs.server
        words = rs.protocol.condition_words
        assert set(srv.guard.words) == set(words)
        page = small.new_page()
        frames = FrameLog().attach(page)
        seen: list[str] = []
        connect_page(page, rs.url)
        code = srv.enrol("P01")
        join(page, code, then=None)
        srv.act(code, "start")
        agree = page.get_by_role("button", name=rs.protocol.texts.consent_agree)
        agree.wait_for()
        seen.append(page.inner_text("body"))
        agree.click()
        _run_once(page, seen)  # practice
        _run_once(page, seen)  # the first task run, in its own scene
        live = srv.session(code)
        for _ in range(60):
            if live.session.phase() == "debrief":
                break
            srv.act(code, "skip", reason="test: on to the next step")
        page.get_by_role("button", name="Finish").wait_for()
        seen.append(page.inner_text("body"))
        page.get_by_role("button", name="Finish").click()
        page.get_by_text("Done").first.wait_for()
        assert wait_until(lambda: rs.store.session("P01").status == "completed")

        # every string of every message, but a field's value that is one of viser's own fixed
        # settings (memory3's "standard" is also every mesh's material), as the guard reads them
        strings = [s for m in frames.messages() for s in iter_strings(m)]
        assert len(strings) > 100 and any("Run finished" in s for s in strings)
        raw = frames.raw_bytes()  # every frame, decompressed, with its binary buffers
        settings = set().union(*FIELD_VALUES.values())
        text = "\n".join(without_client_warning(s) for s in seen).lower()
        for word in words:
            assert not [s for s in strings if word in s.lower()], f"{word!r} in a frame"
            if word not in settings:
                assert word.encode() not in raw, f"{word!r} in a frame's bytes"
            assert word not in text, f"{word!r} on the page"
        assert srv.guard.violations == [] and srv.guard.checked > 100
    finally:
        rs.stop()

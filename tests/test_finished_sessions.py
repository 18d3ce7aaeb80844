"""Finished sessions leave the study server (issue 22: no client may grow the server).

Each finished session used to stay in the server's registry for the life of the process, with
its page thread and its view: an open-link study serving thousands of participants grew with
every one. Now a finished session stays while a tab shows its last screen and for a grace after
that (a reload gets the screen again), then it is closed and let go: its threads end, its code
and cookie read like any wrong code, the console still lists it from the store. Time is driven
by ``drop_finished(now=...)`` or a short ``finished_grace_s``, never by sleeping out the grace.
"""

from __future__ import annotations

import asyncio
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from study.server.firewall import Firewall, FirewallConfig
from study.server.join import ALPHABET
from study.server.live import LiveSession
from study.server.participant_tabs import JOIN_FAILED
from study.server.recruitment import Recruitment
from study.server.server import ServerError, StudyServer
from tests.browser.harness import RunningServer, run_async, start_server, wait_until
from tests.support.raw_client import AGREE, RawClient

END_TEXT = "You may close this page now."
GRACE_S = 60.0
"""The tests' grace: long, so the server's own sweeper never lets a session go before the test
does (``drop_finished(now=...)`` moves the clock)."""


def _roomy() -> Firewall:
    """The port's rules without the gate on new tabs per address (these tabs all come from
    127.0.0.1, one after another; the gate has its own tests)."""
    return Firewall(
        FirewallConfig(new_tabs_per_s=None, accept_burst=500.0, accept_total_per_s=500.0)
    )


def _server(tmp_path: Path, *, grace_s: float = GRACE_S, **kw: Any) -> RunningServer:
    server_kw = {"finished_grace_s": grace_s, "port_firewall": _roomy(), **kw}
    return start_server(tmp_path, time_limit_s=30.0, training_runs=1, server_kw=server_kw)


def _threads_of(code: str) -> list[str]:
    return [t.name for t in threading.enumerate() if t.is_alive() and t.name.endswith(code)]


def _heartbeats() -> int:
    return sum(t.is_alive() and t.name == "lease-heartbeat" for t in threading.enumerate())


def _skip_to_end(srv: StudyServer, code: str) -> None:
    """The experimenter skips every step after consent; the participant finishes."""
    live = srv.session(code)
    while live.session.phase() not in ("debrief", "done"):
        srv.act(code, "skip", reason="test: served to its end")
    live.finish()


def _released(live: LiveSession) -> bool:
    """The page thread found the session over and released it (the grace counts from then)."""
    return live.over_and_left_s(time.monotonic()) is not None


def _later(s: float) -> float:
    return time.monotonic() + s


def _markdown(c: RawClient) -> list[str]:
    return [
        str(m["props"]["_markdown"])
        for m in c.messages
        if m.get("type") == "GuiMarkdownMessage" and "props" in m
    ]


def _wrong(code: str) -> str:
    """A well-formed code that is not ``code``."""
    return "".join(ALPHABET[(ALPHABET.index(ch) + 1) % len(ALPHABET)] for ch in code)


def test_a_finished_session_without_a_tab_leaves_after_the_grace_with_its_threads(
    tmp_path: Path,
) -> None:
    rs = _server(tmp_path)
    srv, store = rs.server, rs.store
    heartbeats = _heartbeats()  # other tests' in this worker, if any left theirs
    try:
        code = srv.enrol("P01")
        srv.act(code, "start")
        live = srv.session(code)
        live.agree()
        live.start_trial()  # a run: its control loop, render loop and view from above
        assert wait_until(lambda: live.run is not None and live.run.ticks > 5, timeout=20)
        assert wait_until(lambda: len(_threads_of(code)) >= 3, timeout=10)
        assert f"page-{code}" in _threads_of(code) and f"control-{code}" in _threads_of(code)
        assert wait_until(lambda: live.started_at() is not None, timeout=5)
        srv.act(code, "end", reason="test: the participant had to leave")
        assert wait_until(lambda: _released(live), timeout=10)
        assert srv.drop_finished(now=_later(GRACE_S - 5)) == []  # within the grace: stays
        assert srv.sessions() == [live]

        assert srv.drop_finished(now=_later(GRACE_S + 1)) == ["P01"]
        assert srv.sessions() == [] and srv.find(code) is None
        assert _threads_of(code) == []  # close() joined them all
        assert _heartbeats() <= heartbeats  # its lease's heartbeat ended too
        assert store.conn.execute("SELECT COUNT(*) FROM leases").fetchone()[0] == 0

        # the console: still listed, its detail from the store, actions refused with the reason
        (row,) = srv.summaries()
        assert (row.code, row.participant, row.state) == (code, "P01", "ended / done")
        assert row.elapsed_s is not None and not row.connected
        detail = srv.detail(code)
        assert detail is not None and detail.actions == ()
        assert detail.condition.startswith("none: the session is ended; no longer live")
        assert [t[2] for t in detail.trials] == ["interrupted"]  # the run the end cut short
        assert "**ended**: test: the participant had to leave" in [r[2] for r in detail.timeline]
        with pytest.raises(ServerError, match="over and no longer live"):
            srv.act(code, "resume")
        srv.console.select(code)
        srv.console.refresh()
        assert "**P01**" in srv.console.status_md.content
        assert "no longer live" in srv.console.status_md.content
        assert f"`{code}`" in srv.console.sessions_md.content
        assert all(b.disabled for b in srv.console.action_buttons.values())
        assert srv.reopenable() == []
    finally:
        rs.stop()


def test_a_tab_on_the_last_screen_keeps_it_a_reload_gets_it_and_later_nothing(
    tmp_path: Path,
) -> None:
    rs = _server(tmp_path)
    srv = rs.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    token = srv.session_token(code)
    cookie = {"Cookie": f"study-rejoin={token}"}
    live = srv.session(code)

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as tab:
            await tab.join(code)
            await tab.click(AGREE)
            assert wait_until(lambda: live.session.phase() != "consent", timeout=5)
            await asyncio.to_thread(_skip_to_end, srv, code)
            await tab.wait_for(lambda m: END_TEXT in str(m.get("props", {}).get("_markdown")))
            assert wait_until(lambda: live.ended_at is not None, timeout=5)
            assert srv.drop_finished(now=_later(10 * GRACE_S)) == []  # the tab still shows it
        assert await asyncio.to_thread(wait_until, lambda: live.page is None, timeout=5)

        # a reload within the grace presents its cookie: the last screen again, no join error
        async with RawClient(srv.participant_port, headers=cookie) as reload:
            await reload.wait_for(lambda m: END_TEXT in str(m.get("props", {}).get("_markdown")))
            assert not any(JOIN_FAILED in t for t in _markdown(reload))
            assert srv.drop_finished(now=_later(10 * GRACE_S)) == []
        assert await asyncio.to_thread(wait_until, lambda: live.page is None, timeout=5)
        async with RawClient(srv.participant_port) as typed:  # its code typed: a wrong code's reply
            await typed.type_code(code)
            await typed.wait_for(lambda m: JOIN_FAILED in str(m.get("props", {}).get("_markdown")))

        # the grace counts from the reload's tab leaving; then the session is let go
        assert srv.drop_finished(now=_later(GRACE_S - 5)) == []
        assert srv.drop_finished(now=_later(GRACE_S + 1)) == ["P01"]
        assert _threads_of(code) == []

        replies = []
        for headers, typed_code in ((cookie, code), (None, code), (None, _wrong(code))):
            async with RawClient(srv.participant_port, headers=headers) as c:
                await c.type_code(typed_code)  # the cookie's tab is asked for a code, as any
                await c.wait_for(lambda m: JOIN_FAILED in str(m.get("props", {}).get("_markdown")))
                assert not any(END_TEXT in t for t in _markdown(c))
                replies.append(sorted(t for t in _markdown(c) if JOIN_FAILED in t))
        assert replies[0] == replies[1] == replies[2]  # its code and cookie: any wrong code's

    try:
        run_async(scenario())
        assert srv.sessions() == [] and [r.participant for r in srv.summaries()] == ["P01"]
    finally:
        rs.stop()


def test_a_finished_link_participant_coming_back_is_not_enrolled_again(tmp_path: Path) -> None:
    rs = _server(tmp_path, open_link=3)
    srv, store = rs.server, rs.store
    person = Recruitment((("PROLIFIC_PID", "5f1a"),))
    try:
        live, _ = srv.link_session(person, address="10.0.0.1")
        assert live is not None and live.participant == "L0001"
        live.act("start")
        live.agree()
        _skip_to_end(srv, live.code)
        assert wait_until(lambda: _released(live), timeout=10)
        assert srv.link_session(person, address="10.0.0.1") == (None, "completed")  # as before
        assert srv.drop_finished(now=_later(GRACE_S + 1)) == ["L0001"]

        assert srv.link_session(person, address="10.0.0.2") == (None, "completed")  # its end
        assert [p.participant for p in store.participants()] == ["L0001"]
        assert srv.sessions() == [] and srv.link().used == 1
        (row,) = srv.summaries()
        assert (row.participant, row.source) == ("L0001", "link")
        detail = srv.detail(row.code)
        assert detail is not None and detail.recruitment == (("PROLIFIC_PID", "5f1a"),)
        with pytest.raises(ServerError, match="over and no longer live"):
            srv.session(row.code)
    finally:
        rs.stop()


def _serve(srv: StudyServer, participant: str, *, tab: bool) -> None:
    """One participant's whole session, with or without a tab that joins and leaves."""
    code = srv.enrol(participant)
    srv.act(code, "start")
    live = srv.session(code)
    if not tab:
        live.agree()
        _skip_to_end(srv, code)
        return

    async def visit() -> None:
        async with RawClient(srv.participant_port) as c:
            await c.join(code)
            await c.click(AGREE)
            assert wait_until(lambda: live.session.phase() != "consent", timeout=5)
            await asyncio.to_thread(_skip_to_end, srv, code)
            await c.wait_for(lambda m: END_TEXT in str(m.get("props", {}).get("_markdown")))

    run_async(visit())


def test_thirty_short_sessions_leave_the_threads_and_the_registry_flat(tmp_path: Path) -> None:
    """Served one after the other to their end (every fifth with a tab that joins, consents,
    reads the end screen and leaves), with a grace of 0.2 s: the registry holds only the
    newest, and the process's threads are what they were after the first five."""
    rs = _server(tmp_path, grace_s=0.2)
    srv = rs.server
    try:
        for n in range(5):
            _serve(srv, f"P{n:02d}", tab=n == 0)
        assert wait_until(lambda: not srv.sessions(), timeout=10)
        threads = threading.active_count()
        most = 0
        for n in range(5, 30):
            _serve(srv, f"P{n:02d}", tab=n % 5 == 0)
            most = max(most, len(srv.sessions()))
        assert wait_until(lambda: not srv.sessions(), timeout=10)
        assert wait_until(lambda: threading.active_count() <= threads, timeout=10), [
            t.name for t in threading.enumerate()
        ]
        print(f"threads {threads} -> {threading.active_count()}, registry at most {most} of 25")
        assert most < 25  # let go while the others were served, not only at the end
        assert len(srv.summaries()) == 30
        assert {r.state for r in srv.summaries()} == {"completed / done"}
    finally:
        rs.stop()


def test_a_code_is_never_given_twice_even_after_its_session_left(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A finished participant who types their old code must never join another's session: the
    server gives no code twice, also after the session (and the console's 500 rows) let go."""
    from study.server import join

    drawn = iter(["AAAAAA", "AAAAAA", "CCCCCC", "CCCCCC", "DDDDDD"])
    draw = join._random

    def codes_repeat(length: int, words: tuple[str, ...]) -> str:
        return next(drawn) if length == join.CODE_LENGTH else draw(length, words)  # tokens

    monkeypatch.setattr(join, "_random", codes_repeat)
    rs = _server(tmp_path)
    srv = rs.server
    try:
        first = srv.enrol("P01")
        assert first == "AAAAAA"
        srv.act(first, "end", reason="test: the participant left")
        assert wait_until(lambda: _released(srv.session(first)), timeout=10)
        assert srv.drop_finished(now=_later(GRACE_S + 1)) == ["P01"]
        srv._retired.clear()  # as if 500 later sessions had pushed its row out of the console
        assert srv.enrol("P02") == "CCCCCC"  # "AAAAAA" drawn again and refused
        assert srv.enrol("P03") == "DDDDDD"  # and "CCCCCC" is live
    finally:
        rs.stop()

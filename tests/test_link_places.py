"""The open link's places held by sessions nobody uses are given back.

A script with made-up recruitment IDs once filled every place of a link (50 in 20 s) and kept
them, with a lease and threads each, for as long as the server ran: a real participant then
found the link full. A link session left before consent without a tab for the idle time now
gives its place back; its ID coming back gets the same session; a restart remembers.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from study.server.console_texts import link_markdown
from study.server.open_link import LinkClosed, OpenLink
from study.server.recruitment import Recruitment
from study.session import open_store
from tests.browser.harness import start_server, wait_until


def _threads_of(code: str) -> list[str]:
    return [t.name for t in threading.enumerate() if t.is_alive() and code in t.name]


def test_bots_that_never_consent_give_their_places_back_and_a_returning_id_its_session(
    tmp_path: Path,
) -> None:
    rs = start_server(tmp_path, server_kw={"open_link": 2, "link_idle_s": 1.0})
    srv, store = rs.server, rs.store
    try:
        bots = [Recruitment((("pid", f"bot{n}"),)) for n in range(2)]
        opened = [srv.link_session(r, address=f"10.0.0.{n}")[0] for n, r in enumerate(bots)]
        assert all(live is not None for live in opened)
        started = opened[1]
        assert started is not None
        started.act("start")  # its tab saw the consent screen, then left
        assert srv.link().used == 2
        with pytest.raises(LinkClosed, match="all 2 places"):
            srv.link_session(Recruitment((("pid", "person"),)), address="10.0.0.9")
        assert "New IDs refused: 1 while it was full." in link_markdown(srv.link())
        codes = [live.code for live in opened if live is not None]
        assert any(_threads_of(c) for c in codes)
        assert wait_until(lambda: srv.link().used == 0, timeout=10.0)
        assert not srv.sessions()  # closed: no lease held, no thread left
        assert wait_until(lambda: not any(_threads_of(c) for c in codes), timeout=5.0)
        assert store.conn.execute("SELECT COUNT(*) FROM leases").fetchone()[0] == 0
        assert srv.reopenable() == []  # not the console's to reopen: they come by their link
        released = [e.participant for e in store.events() if e.kind == "link_place_released"]
        assert sorted(released) == ["L0001", "L0002"]

        person, _ = srv.link_session(Recruitment((("pid", "person"),)), address="10.0.0.9")
        assert person is not None and person.participant == "L0003"
        back, _ = srv.link_session(bots[1], address="10.0.0.1")  # the same ID: the same session
        assert back is not None and back.participant == "L0002"
        assert srv.link().used == 2
    finally:
        rs.stop()
    with open_store(store.path, rs.protocol) as reopened:  # a restart: L0001 stays given back
        again = OpenLink(reopened, enabled=True, cap=2)
        assert again.released() == {"L0001"} and again.used() == 2


def test_a_session_whose_tab_is_there_or_that_got_past_consent_keeps_its_place(
    tmp_path: Path,
) -> None:
    rs = start_server(tmp_path, server_kw={"open_link": 3, "link_idle_s": 0.5})
    srv = rs.server
    try:
        live, _ = srv.link_session(Recruitment((("pid", "reader"),)))
        assert live is not None
        live.act("start")
        live.session.agree()  # consented: a participant who then left keeps the place
        assert wait_until(lambda: live.unattended_s(time.monotonic()) > 1.5, timeout=5)
        assert srv.reclaim_link_places() == []
        assert srv.link().used == 1 and srv.sessions() == [live]
    finally:
        rs.stop()

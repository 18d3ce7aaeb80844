"""``ParticipantTabs``: the participant port's tabs, from a connection to a bound session.

A tab that connects types the join code the experimenter's console shows (guesses are
throttled per tab and per address, and every failed code gets the same reply); a tab that held
a session keeps its rejoin token in a cookie, so a reload or a reconnect rejoins at once; only
on a kiosk (one machine, one participant at a time) does a tab bind to the one open session
without a code. While the open link is in use, a new tab first says what its URL carries, and
a tab whose URL carries a recruitment ID joins its ID's session by the link
(:mod:`study.server.open_link`). A session is bound to one tab at a time; when that tab goes
away its running trial pauses and the session waits for its code again. A finished session's
tab that reloads (its rejoin cookie) gets the last screen again until the server lets the
session go (:mod:`study.server.finished_sessions`); afterwards, as for any wrong code, the join
screen.

The tabs share the study server's lock (``StudyServer._lock``): every change of who holds
which session happens under it.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import threading
import time
from typing import Protocol

import viser

from study.server import viser_door
from study.server.blinding_guard import BlindingGuard
from study.server.firewall import REJOIN_COOKIE, Firewall
from study.server.join import JoinThrottle, normalize_code
from study.server.live import LiveSession, SessionFactory
from study.server.live.screens import show_end
from study.server.live.texts import (
    LINK_CLOSED_TEXT,
    LINK_FAILED_TEXT,
    LINK_IN_USE_TEXT,
    LINK_INVALID_TEXT,
)
from study.server.open_link import LinkClosed, OpenLink
from study.server.page_scene import frame_task
from study.server.participant_page import ParticipantPage
from study.server.recruitment import LinkError, Recruitment, parse_ids, read_link

LOGGER = logging.getLogger("study.server.server")

PAGE_TITLE = "Robot arm study"
JOIN_FAILED = "That code did not work. Please check it with the experimenter and type it again."
REJOIN_WAIT_S = 45.0
"""How long a tab with a rejoin token waits for the session's old tab to be let go (longer than
the websocket's ping interval plus timeout, 20 + 20 s)."""
REJOIN_KEEP_S = 12 * 3600
"""How long a tab keeps its rejoin cookie (a day's session at most)."""
JOIN_THROTTLED = "Too many tries. Please wait a minute, then ask the experimenter for the code."
LINK_QUIET_S = 2.0
"""How long a link tab waits for its session's old tab to let go (a reload) before it is told
that the study is open in another tab."""


class TabsServer(Protocol):
    """What the tabs need of their study server (``StudyServer`` has it): its participant
    port, firewall, blinding guard, join throttle, open link and session factory, its lock,
    and its sessions by join code, rejoin token and recruitment link."""

    participant: viser.ViserServer
    firewall: Firewall
    guard: BlindingGuard
    throttle: JoinThrottle
    open_link: OpenLink
    factory: SessionFactory
    kiosk: bool
    _lock: threading.RLock

    def find(self, code: str) -> LiveSession | None: ...

    def session_token(self, code: str) -> str: ...

    def by_link(self, code: str) -> bool: ...

    def code_of(self, token: str | None, *, finished: bool = False) -> str | None: ...

    def open_sessions(self) -> list[LiveSession]: ...

    def link_session(
        self, recruitment: Recruitment, *, address: str = "unknown"
    ) -> tuple[LiveSession | None, str]: ...


class ParticipantTabs:
    """The participant port's open tabs and the session each holds, for one study server."""

    def __init__(self, server: TabsServer) -> None:
        self.server = server
        self._lock = server._lock
        self._throttle_logged = 0.0
        self._pages: dict[int, ParticipantPage] = {}
        self._page_session: dict[int, str] = {}
        self._link_pages: set[int] = set()
        """Tabs that came with a recruitment ID: they get no join-code screen."""
        self._greeting: set[int] = set()
        """Tabs whose URL is being read: no join screen until it is known (a code typed
        meanwhile and a recruitment ID answered later once bound one tab to two sessions)."""
        self._link_logged: dict[str, float] = {}

    def counts(self) -> tuple[int, int]:
        """(open tabs, tabs that hold a session)."""
        with self._lock:
            return len(self._pages), len(self._page_session)

    def holds(self, code: str) -> bool:
        """Whether a tab holds (or is being bound to) session ``code``."""
        with self._lock:
            return code in self._page_session.values()

    def session_code(self, client_id: int) -> str | None:
        """The join code of the session tab ``client_id`` holds (no lock: safe on the event
        loop, which must never wait for an enrolment)."""
        return self._page_session.get(client_id)

    def address(self, client_id: int) -> str:
        """The address a participant tab connected from ("unknown" if viser hides it): behind a
        trusted proxy, the client's address the proxy forwarded."""
        connection = viser_door.connection_of(self.server.participant, client_id)
        if connection is None:
            return "unknown"
        return self.server.firewall.client_host(connection)

    def connected(self, client: viser.ClientHandle) -> None:
        page = ParticipantPage(
            client,
            title=PAGE_TITLE,
            words=self.server.guard.words,
            listening=self.server.listening,
        )
        page.address = self.address(client.client_id)
        try:
            frame_task(client.camera, look_at=(0.45, 0.0, 0.15))
        except Exception:  # a camera state viser cannot turn (the firewall refuses degenerate ones)
            LOGGER.warning("could not frame the task view for a new tab", exc_info=True)
        with self._lock:
            # viser runs connect and disconnect callbacks in a pool, in no fixed order: a tab
            # that left before we got here must not be registered (it would hold a session)
            if client.client_id not in self.server.participant.get_clients():
                return
            self._pages[client.client_id] = page
        token = self.server.firewall.token_of(client.client_id)
        code = self.server.code_of(token, finished=True)  # finished: its last screen again
        if code is not None and self.server.by_link(code):
            code = None  # the link's tab: its URL's ID decides (another tab is told, not held)
        if code is not None:  # a reload that kept its session's rejoin token
            threading.Thread(
                target=self._rejoin, args=(page, code), name="rejoin", daemon=True
            ).start()
        elif not self.server.open_link.in_use():
            self._offer(page)  # a lab study: the join screen at once, no URL read
        else:
            with self._lock:
                self._greeting.add(client.client_id)
            threading.Thread(target=self._greet, args=(page,), name="greet", daemon=True).start()

    def _greet(self, page: ParticipantPage) -> None:
        """A new tab while the open link is in use: with a recruitment ID in its URL, the open
        link's way in; else the join code (offered only once the URL is known)."""
        cid = page.client.client_id
        try:
            values = read_link(page)
        except Exception:  # the tab went away
            values = {}
        try:
            recruitment = parse_ids(values)
        except LinkError as exc:
            self._note_link("invalid", f"link refused (last from {page.address}): {exc}")
            with self._lock:
                self._link_pages.add(cid)
                self._greeting.discard(cid)
            page.show_message("This link does not work", LINK_INVALID_TEXT)
            return
        with self._lock:
            if recruitment is not None:
                self._link_pages.add(cid)
            self._greeting.discard(cid)
        if recruitment is not None:
            self._link_join(page, recruitment)
            return
        self._offer(page)

    def _rejoin(self, page: ParticipantPage, code: str) -> None:
        """A reloaded (or reconnected) tab that presented its session's rejoin token at the
        door: bind it without a code and without the throttle. While the session's old tab is
        still held -- a dropped network connection is only noticed after the websocket's ping
        timeout -- wait for it to let go; the join screen shows meanwhile. (An open link's
        tab comes back by its link instead: ``_greet``.)"""
        self._offer(page)
        deadline = time.monotonic() + REJOIN_WAIT_S
        while time.monotonic() < deadline:
            with self._lock:
                live = self.server.find(code)
                gone = page.client.client_id not in self._pages
            if gone or live is None or live.page is None:
                break
            time.sleep(0.25)
        with self._lock:
            bound = page.client.client_id in self._page_session
        if not bound:
            self._join(page, code, proven=True)

    def _link_join(self, page: ParticipantPage, recruitment: Recruitment) -> None:
        """Bind a link tab to its recruitment ID's session: the one it had (reopened after a
        restart; its end screen if it finished), or a new one while the link has places. While
        another tab holds the session this one waits, is told so after ``LINK_QUIET_S``, and
        takes over only once that tab has let go (within ``REJOIN_WAIT_S``; later, a reload
        asks again). A new session starts by itself: no experimenter is there to start it."""
        try:
            live, ended = self.server.link_session(recruitment, address=page.address)
        except LinkClosed as exc:
            self._note_link("closed", f"open link refused a new participant: {exc}")
            page.show_message("Not open at the moment", LINK_CLOSED_TEXT)
            return
        except Exception:  # the store refused, the session is held elsewhere: say so, go on
            LOGGER.exception("open link: no session for a tab from %s", page.address)
            page.show_message("Please try again", LINK_FAILED_TEXT)
            return
        if live is None:
            show_end(page, ended, self.server.factory.protocol.texts.for_link())
            return
        start = time.monotonic()
        told = False
        while not self.bind(page, live):
            if not told and time.monotonic() - start > LINK_QUIET_S:
                told = True
                live.note_refused_join(page)
                page.show_message("Already open", LINK_IN_USE_TEXT)
            with self._lock:
                gone = page.client.client_id not in self._pages
                let_go = self.server.find(live.code) is not live
            if gone or let_go or live.closed or time.monotonic() - start > REJOIN_WAIT_S:
                return
            time.sleep(0.25)
        if live.session.phase() == "waiting":
            try:
                live.act("start")
            except Exception as exc:
                LOGGER.warning("link session %s could not start: %s", live.code, exc)

    def _note_link(self, key: str, text: str) -> None:
        """Log a refused link at most once a minute per kind (any tab can cause one)."""
        now = time.monotonic()
        with self._lock:
            if now - self._link_logged.get(key, -math.inf) < 60.0:
                return
            self._link_logged[key] = now
        LOGGER.info("%s", text)

    def disconnected(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._link_pages.discard(client.client_id)
            self._greeting.discard(client.client_id)
            page = self._pages.pop(client.client_id, None)
            code = self._page_session.pop(client.client_id, None)
            live = self.server.find(code) if code is not None else None
        self.server.throttle.forget_client(client.client_id)
        self.server.firewall.bind(client.client_id, False)
        if live is not None and page is not None:
            live.detach(page)
        self.offer_all()

    def offer_all(self) -> None:
        with self._lock:
            pages = [p for cid, p in self._pages.items() if cid not in self._page_session]
        for page in pages:
            self._offer(page)

    def _offer(self, page: ParticipantPage) -> None:
        """Ask ``page`` for a join code (on a kiosk: bind it to the one free session, or ask
        it to wait)."""
        with self._lock:
            cid = page.client.client_id
            if cid in self._page_session or cid in self._link_pages or cid in self._greeting:
                return
            open_ = self.server.open_sessions()
        if self.server.kiosk:
            # only a session no tab has held yet: after a drop, only the tab that kept the
            # code (or one that types it) gets the session back
            fresh = [s for s in open_ if s.page is None and not s.ever_attached]
            if len(open_) == 1 and fresh:
                self.bind(page, fresh[0])
                return
            if not open_:
                if page.screen_name != "join" or page.asks_code:
                    page.show_join(ask_code=False, on_code=lambda _c: None)
                return
        if page.screen_name != "join" or not page.asks_code:
            page.show_join(ask_code=True, on_code=lambda code, p=page: self._join(p, code))

    def _join(self, page: ParticipantPage, typed: str, *, proven: bool = False) -> None:
        """A typed code: bind on a match; the same reply for any failure (wrong, closed, in
        use), and no check at all once this tab or its address tried too often. A ``proven``
        code (its tab presented the session's rejoin token) skips the throttle; if it no
        longer works, the tab forgets it and is asked for a code."""
        address = getattr(page, "address", "unknown")
        if not proven and not self.server.throttle.allow(
            client=page.client.client_id, address=address
        ):
            now = time.monotonic()
            if now - self._throttle_logged > 60.0:
                self._throttle_logged = now
                LOGGER.warning(
                    "join attempts throttled (last from %s%s)",
                    address,
                    "; the server-wide budget is spent: someone may be guessing codes"
                    if self.server.throttle.saturated()
                    else "",
                )
            page.show_join(
                ask_code=True, on_code=lambda c, p=page: self._join(p, c), notice=JOIN_THROTTLED
            )
            return
        code = normalize_code(typed)
        with self._lock:
            live = self.server.find(code)
        if proven and live is not None and live.closed and self.bind(page, live):
            return  # a reload of a finished session not yet let go: its last screen again
        if live is None or live.closed or not self.bind(page, live):
            if live is not None and not live.closed:
                live.note_refused_join(page)
            if proven and (live is None or live.closed):
                # the token's session is over; one still held by another tab (a second tab of
                # the same browser, which shares the cookie) keeps it for that tab's reload
                with contextlib.suppress(Exception):
                    page.run_script(_cookie_script(""))
            if proven:
                with self._lock:
                    link_page = page.client.client_id in self._link_pages
                if link_page:  # a reload then comes in by its link again
                    page.show_message("Please try again", LINK_FAILED_TEXT)
                self._offer(page)
                return
            page.show_join(
                ask_code=True, on_code=lambda c, p=page: self._join(p, c), notice=JOIN_FAILED
            )

    def bind(self, page: ParticipantPage, live: LiveSession) -> bool:
        """Bind ``page`` to ``live`` unless another tab holds it or the server let it go;
        True when bound."""
        with self._lock:
            if page.client.client_id not in self._pages:
                return True  # the tab closed meanwhile: nothing to tell it
            if self.server.find(live.code) is not live:
                return False  # let go meanwhile (finished, or its link place given back)
            if live.page is not None and live.page is not page:
                return False
            if self._page_session.get(page.client.client_id, live.code) != live.code:
                return False  # one tab, one session: it holds another already
            self._page_session[page.client.client_id] = live.code
        live.attach(page)
        with self._lock:
            gone = page.client.client_id not in self._pages
        if gone:  # the tab left while it was being attached: let the session go again
            with self._lock:
                self._page_session.pop(page.client.client_id, None)
            live.detach(page)
            return True
        self.server.firewall.bind(page.client.client_id)
        with self._lock:
            token = self.server.session_token(live.code)
        with contextlib.suppress(Exception):  # the tab keeps its token for a reload
            page.run_script(_cookie_script(token))
        return True


def _cookie_script(value: str) -> str:
    """JavaScript that keeps ``value`` in the tab's rejoin cookie (an empty value clears it)."""
    age = REJOIN_KEEP_S if value else 0
    cookie = f"{REJOIN_COOKIE}={value}; path=/; max-age={age}; SameSite=Strict"
    return f"document.cookie = {json.dumps(cookie)};"

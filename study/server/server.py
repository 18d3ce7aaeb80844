"""The study server: two viser servers in one process and the registry of live sessions.

* Participant view: a ``ViserServer`` on the LAN (``0.0.0.0``), guarded outbound by the
  blinding guard and inbound by a :class:`~study.server.firewall.Firewall` (an allow-list of message
  types, bounded values and sizes, no share links, fair shares for tabs that hold no session).
  A tab that connects types the join code the experimenter's console shows (guesses are
  throttled per tab and per address, and every failed code gets the same reply); a tab that
  held a session keeps its rejoin token in a cookie, so a reload or a reconnect rejoins at once
  (and gets a slot even when the port is full); only on a kiosk (``kiosk=True``, one machine, one
  participant at a time) does a tab bind to the one open session without a code. A session is
  bound to one tab at a time; when that tab goes away (reload, lost connection) its running
  trial pauses and the session waits for its code again.
* Open enrolment (online studies, off by default): once it is on (or has enrolled anyone), a
  new tab first says what its URL carries, and a tab whose URL carries a recruitment ID
  (``?PROLIFIC_PID=...`` or ``?pid=...``, :mod:`study.server.recruitment`) gets a session
  without a code while the link is on and has places (:mod:`study.server.open_link`); the
  session starts at once. One session per recruitment ID: a reload with the same ID rejoins
  it, another tab with the same ID waits (and is told so) while the first holds it.
* Behind a TLS reverse proxy (``trusted_proxies``), limits and logs use the client address
  the proxy forwards and the ``Origin`` check accepts the public host name it forwards
  (:mod:`study.server.forwarded`).
* Experimenter view: a second ``ViserServer`` on ``127.0.0.1`` only, so the participant's
  machine has no route to it. The two servers share nothing but this object.

viser runs callbacks in a thread pool; every registry change happens under ``self._lock``.
"""

from __future__ import annotations

import contextlib
import hmac
import json
import logging
import math
import threading
import time
from collections.abc import Iterable
from pathlib import Path

import viser

from study.protocol.blinding import find_words
from study.server import blinding_guard, firewall, logs, realtime
from study.server.console_page import (
    ExperimenterConsole,
    LinkState,
    SessionDetail,
    SessionSummary,
    StudyProgress,
)
from study.server.firewall import LOOPBACK_NAMES, REJOIN_COOKIE
from study.server.forwarded import Network
from study.server.join import JoinThrottle, new_join_code, new_token, normalize_code
from study.server.live import LiveSession, SessionFactory
from study.server.live.progress import study_progress
from study.server.live.screens import show_end
from study.server.live.texts import (
    LINK_CLOSED_TEXT,
    LINK_FAILED_TEXT,
    LINK_IN_USE_TEXT,
    LINK_INVALID_TEXT,
)
from study.server.open_link import LinkClosed, OpenLink
from study.server.page_head import PageHead
from study.server.page_scene import frame_task
from study.server.page_script import page_script
from study.server.participant_page import ParticipantPage
from study.server.recruitment import LinkError, Recruitment, link_script, parse_ids, read_link
from study.session import EXPERIMENTER_ACTIONS, FINAL_STATUSES

LOGGER = logging.getLogger("study.server.server")

PAGE_TITLE = "Robot arm study"


class ServerError(RuntimeError):
    """The study server cannot do what was asked (unknown session code, duplicate ...)."""


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


class StudyServer:
    """Owns the participant and experimenter ``ViserServer``s and the live sessions.

    ``condition_words``: what the participant's page must never receive, the served
    protocol's :attr:`~study.protocol.Protocol.condition_words`."""

    def __init__(
        self,
        factory: SessionFactory,
        *,
        condition_words: Iterable[str],
        host: str = "0.0.0.0",
        port: int = 8080,
        experimenter_host: str = "127.0.0.1",
        experimenter_port: int = 8081,
        render_hz: float = 60.0,
        verbose: bool = False,
        console_refresh_hz: float = 5.0,
        kiosk: bool = False,
        allow_share: bool = False,
        throttle: JoinThrottle | None = None,
        open_link: int = 0,
        public_url: str | None = None,
        trusted_proxies: tuple[Network, ...] = (),
        port_firewall: firewall.Firewall | None = None,
        log_path: Path | None = None,
    ) -> None:
        """``open_link``: places of the open-enrolment link (0: off; the console turns it on
        and off); ``public_url``: the participants' address as they reach it (behind a
        proxy), shown with the link; ``trusted_proxies``: reverse proxies whose forwarded
        client address and host name count (``study.server.forwarded``); ``port_firewall``:
        the participant port's rules (a default ``Firewall`` if not given; tests and
        benchmarks pass one with other limits); ``log_path``: the server's log file
        (``study.server.logs``), whose disk use the console shows."""
        self.log_path = log_path
        self.factory = factory
        self.render_hz = render_hz
        self.kiosk = kiosk
        self.throttle = throttle or JoinThrottle()
        self._throttle_logged = 0.0
        self._lock = threading.RLock()
        self._sessions: dict[str, LiveSession] = {}
        self._pages: dict[int, ParticipantPage] = {}
        self._page_session: dict[int, str] = {}
        self._link_pages: set[int] = set()
        """Tabs that came with a recruitment ID: they get no join-code screen."""
        self._greeting: set[int] = set()
        """Tabs whose URL is being read: no join screen until it is known (a code typed
        meanwhile and a recruitment ID answered later once bound one tab to two sessions)."""
        self._link_logged: dict[str, float] = {}
        self.public_url = public_url
        self.open_link = OpenLink(factory.store, enabled=open_link > 0, cap=open_link)
        self._tokens: dict[str, str] = {}
        """Each session's rejoin token, by join code."""

        self.firewall = port_firewall or firewall.Firewall(
            allow_share=allow_share, trusted_proxies=trusted_proxies
        )
        self.firewall.rejoin_token = self._proven_token
        self.firewall.on_bound_drop = self._bound_input_dropped
        self.firewall.page_filter = PageHead()  # viser's own notices hidden from the first paint
        with firewall.hardened_serve(self.firewall):
            self.participant = viser.ViserServer(host=host, port=port, verbose=verbose)
        self.guard = blinding_guard.install(self.participant, words=condition_words)
        _check_page_is_blind(self.guard.words)
        firewall.install(self.participant, self.firewall)
        self.participant.gui.configure_theme(
            show_share_button=False, show_logo=False, control_width="large"
        )
        self.participant.scene.world_axes.visible = False
        self.participant.on_client_connect(self._participant_connected)
        self.participant.on_client_disconnect(self._participant_disconnected)

        # the console may use every message type; share links stay off unless asked for, and
        # no page of another site open in the experimenter's browser may drive it (origin)
        self.experimenter_firewall = firewall.Firewall(
            allowed=None,
            allow_share=allow_share,
            max_bytes=8 * 2**20,
            rate_per_s=2000.0,
            loopback_only=experimenter_host in LOOPBACK_NAMES,
            shares_per_s=None,  # the experimenter's own tabs: no shares, never idle-closed
            idle_timeout_s=None,
        )
        with firewall.hardened_serve(self.experimenter_firewall):
            self.experimenter = viser.ViserServer(
                host=experimenter_host, port=experimenter_port, verbose=verbose
            )
        firewall.install(self.experimenter, self.experimenter_firewall)
        self.console = ExperimenterConsole(self.experimenter, self, refresh_hz=console_refresh_hz)
        realtime.freeze_heap()  # after start-up: collections never walk it again

    # -- addresses ---------------------------------------------------------------------------
    @property
    def participant_port(self) -> int:
        return self.participant.get_port()

    @property
    def experimenter_port(self) -> int:
        return self.experimenter.get_port()

    def urls(self, *, lan_host: str | None = None) -> tuple[str, str]:
        if self.public_url:
            participant_url = self.public_url.rstrip("/")
        else:
            host = lan_host or self.participant.get_host()
            if host in ("0.0.0.0", ""):
                host = _lan_address()
            participant_url = f"http://{host}:{self.participant_port}"
        return participant_url, f"http://127.0.0.1:{self.experimenter_port}"

    def link_url(self) -> str:
        """The open link as a recruitment site takes it (Prolific fills its placeholders)."""
        base = self.urls()[0]
        return (
            f"{base}/?PROLIFIC_PID={{{{%PROLIFIC_PID%}}}}&STUDY_ID={{{{%STUDY_ID%}}}}"
            f"&SESSION_ID={{{{%SESSION_ID%}}}}"
        )

    def stop(self) -> None:
        self.console.close()
        with self._lock:
            sessions = list(self._sessions.values())
        for live in sessions:
            live.close()
        blinding_guard.uninstall(self.participant)
        firewall.uninstall(self.participant)
        firewall.uninstall(self.experimenter)
        self.participant.stop()
        self.experimenter.stop()
        realtime.thaw_heap()

    # -- sessions ----------------------------------------------------------------------------
    def enrol(self, participant: str, *, recruitment: Recruitment | None = None) -> str:
        """Enrol ``participant`` (or reopen their session) and return its join code."""
        with self._lock:
            for code, live in self._sessions.items():
                if live.participant == participant and not live.closed:
                    return code
            words = self.guard.words
            code = new_join_code(set(self._sessions), avoid=words)
            live = self.factory(
                participant,
                code=code,
                title=PAGE_TITLE,
                render_hz=self.render_hz,
                recruitment=recruitment.as_dict() if recruitment else None,
            )
            if recruitment is None and (known := self.open_link.recruitment_of(participant)):
                live.recruitment = known.ids
            live.on_closed = lambda: self._offer_all()
            self._sessions[code] = live
            self._tokens[code] = new_token(avoid=words)
        LOGGER.info("session %s opened for %s", code, participant)
        self._offer_all()
        return code

    def reopenable(self) -> list[str]:
        """Unfinished sessions in the store that no live session holds (a restart or crash
        left them): the console can reopen them."""
        with self._lock:
            open_now = {s.participant for s in self._sessions.values() if not s.closed}
        return self.factory.reopenable(open_now=open_now)

    def reopen(self, participant: str) -> str:
        """Reopen ``participant``'s interrupted session; returns its join code."""
        if participant not in self.reopenable():
            raise ServerError(
                f"{participant!r} has no interrupted session to reopen (finished, open already,"
                " or not enrolled)"
            )
        return self.enrol(participant)

    def session(self, code: str) -> LiveSession:
        with self._lock:
            live = self._sessions.get(code)
        if live is None:
            raise ServerError(f"no session with join code {code!r}; check the console's list")
        return live

    def sessions(self) -> list[LiveSession]:
        with self._lock:
            return list(self._sessions.values())

    def open_sessions(self) -> list[LiveSession]:
        return [s for s in self.sessions() if not s.closed]

    # Console protocol ------------------------------------------------------------------------
    def summaries(self) -> list[SessionSummary]:
        return [s.summary() for s in self.sessions()]

    def detail(self, code: str) -> SessionDetail | None:
        with self._lock:
            live = self._sessions.get(code)
        return None if live is None else live.detail()

    def health(self) -> str:
        """One line for the console: the participant port's tabs and refusals, the log's size."""
        fw = self.firewall
        with self._lock:
            tabs, bound = len(self._pages), len(self._page_session)
        refused = sum(fw.refused_connections.values()) + fw.slots.evicted + fw.slots.timed_out
        line = (
            f"Participant port: {tabs} tab(s), {bound} in a session; {refused} connection(s)"
            f" refused or closed, {sum(fw.dropped.values())} message(s) refused"
        )
        if self.log_path is not None:
            used = logs.disk_use(self.log_path) / 2**20
            cap = (logs.BACKUPS + 1) * logs.MAX_BYTES / 2**20
            line += f". Log: {used:.1f} of at most {cap:.0f} MB (`{self.log_path}`)"
        return line

    def act(self, code: str, action: str, *, reason: str = "") -> str:
        if action not in EXPERIMENTER_ACTIONS:
            actions = ", ".join(EXPERIMENTER_ACTIONS)
            raise ServerError(f"unknown action {action!r}; actions: {actions}")
        result = self.session(code).act(action, reason=reason)
        self._offer_all()
        return result

    def progress(self) -> StudyProgress:
        return study_progress(self.factory.store, self.factory.protocol)

    def link(self) -> LinkState:
        return LinkState(
            enabled=self.open_link.enabled,
            cap=self.open_link.cap,
            used=self.open_link.used(),
            url=self.link_url(),
        )

    def set_link(self, *, enabled: bool, cap: int) -> LinkState:
        self.open_link.configure(enabled=enabled, cap=cap)
        LOGGER.info("open link %s (%d places)", "on" if enabled else "off", cap)
        return self.link()

    # -- participant tabs ----------------------------------------------------------------------
    def _address(self, client_id: int) -> str:
        """The address a participant tab connected from ("unknown" if viser hides it): behind a
        trusted proxy, the client's address the proxy forwarded."""
        connection = self.participant._websock_server._live_connections.get(client_id)
        if connection is None:
            return "unknown"
        return self.firewall.client_host(connection)

    def _participant_connected(self, client: viser.ClientHandle) -> None:
        page = ParticipantPage(client, title=PAGE_TITLE, words=self.guard.words)
        page.address = self._address(client.client_id)
        try:
            frame_task(client.camera, look_at=(0.45, 0.0, 0.15))
        except Exception:  # a camera state viser cannot turn (the firewall refuses degenerate ones)
            LOGGER.warning("could not frame the task view for a new tab", exc_info=True)
        with self._lock:
            # viser runs connect and disconnect callbacks in a pool, in no fixed order: a tab
            # that left before we got here must not be registered (it would hold a session)
            if client.client_id not in self.participant.get_clients():
                return
            self._pages[client.client_id] = page
        code = self._code_of(self.firewall.token_of(client.client_id))
        if code is not None and self._by_link(code):
            code = None  # the link's tab: its URL's ID decides (another tab is told, not held)
        if code is not None:  # a reload that kept its session's rejoin token
            threading.Thread(
                target=self._rejoin, args=(page, code), name="rejoin", daemon=True
            ).start()
        elif not self.open_link.in_use():
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
                live = self._sessions.get(code)
                gone = page.client.client_id not in self._pages
            if gone or live is None or live.page is None:
                break
            time.sleep(0.25)
        with self._lock:
            bound = page.client.client_id in self._page_session
        if not bound:
            self._join(page, code, proven=True)

    def _by_link(self, code: str) -> bool:
        """Whether session ``code`` came by the open link (its tabs come back by their URL)."""
        live = self._sessions.get(code)
        return live is not None and bool(live.recruitment)

    def _proven_token(self, value: str) -> str | None:
        """``value`` (a tab's rejoin cookie) when it is the token of an open session, else
        ``None`` (the firewall asks at the door)."""
        return value if self._code_of(value) is not None else None

    def _code_of(self, token: str | None) -> str | None:
        """The open session whose rejoin token is ``token`` (compared in constant time)."""
        if not token:
            return None
        # no lock: the firewall asks from the event loop, which must never wait for an
        # enrolment (the server's lock is held while a session is built); a dict copy is atomic
        tokens = self._tokens.copy()
        for code, expected in tokens.items():
            if hmac.compare_digest(token.encode(), expected.encode()):
                live = self._sessions.get(code)
                return code if live is not None and not live.closed else None
        return None

    def _bound_input_dropped(self, client_id: int, reason: str) -> None:
        """The firewall refused a message of a session's tab (on the event loop): the session
        records it (from its own worker thread)."""
        code = self._page_session.get(client_id)  # no lock: on the event loop (see _code_of)
        live = self._sessions.get(code) if code is not None else None
        if live is not None:
            live.input.dropped(reason)

    def _link_join(self, page: ParticipantPage, recruitment: Recruitment) -> None:
        """Bind a link tab to its recruitment ID's session: the one it had (reopened after a
        restart; its end screen if it finished), or a new one while the link has places. While
        another tab holds the session this one waits, is told so after ``LINK_QUIET_S``, and
        takes over only once that tab has let go (within ``REJOIN_WAIT_S``; later, a reload
        asks again). A new session starts by itself: no experimenter is there to start it."""
        try:
            live, ended = self._link_session(recruitment, address=page.address)
        except LinkClosed as exc:
            self._note_link("closed", f"open link refused a new participant: {exc}")
            page.show_message("Not open at the moment", LINK_CLOSED_TEXT)
            return
        except Exception:  # the store refused, the session is held elsewhere: say so, go on
            LOGGER.exception("open link: no session for a tab from %s", page.address)
            page.show_message("Please try again", LINK_FAILED_TEXT)
            return
        if live is None:
            show_end(page, ended, self.factory.protocol.texts)
            return
        start = time.monotonic()
        told = False
        while not self._bind(page, live):
            if not told and time.monotonic() - start > LINK_QUIET_S:
                told = True
                live.note_refused_join(page)
                page.show_message("Already open", LINK_IN_USE_TEXT)
            with self._lock:
                gone = page.client.client_id not in self._pages
            if gone or live.closed or time.monotonic() - start > REJOIN_WAIT_S:
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

    def _link_session(
        self, recruitment: Recruitment, *, address: str = "unknown"
    ) -> tuple[LiveSession | None, str]:
        """The live session of ``recruitment`` (enrolled now, or reopened), or ``(None,
        status)`` when its session is over; :class:`LinkClosed` for a new ID while the link
        is off or full. One ID at a time (the server's lock), so an ID gets one session."""
        with self._lock:
            participant = self.open_link.participant_for(recruitment)
            if participant is None:
                participant = self.open_link.claim(recruitment, address=address)
                code = self.enrol(participant, recruitment=recruitment)
                self.open_link.taken(participant, recruitment, address=address)
                return self._sessions[code], ""
            for live in self._sessions.values():
                if live.participant == participant and not live.closed:
                    return live, ""
            status = self.factory.store.session(participant).status
            if status in FINAL_STATUSES:
                return None, status
            return self._sessions[self.enrol(participant)], ""

    def _participant_disconnected(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._link_pages.discard(client.client_id)
            self._greeting.discard(client.client_id)
            page = self._pages.pop(client.client_id, None)
            code = self._page_session.pop(client.client_id, None)
            live = self._sessions.get(code) if code is not None else None
        self.throttle.forget_client(client.client_id)
        self.firewall.bind(client.client_id, False)
        if live is not None and page is not None:
            live.detach(page)
        self._offer_all()

    def _offer_all(self) -> None:
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
            open_ = self.open_sessions()
        if self.kiosk:
            # only a session no tab has held yet: after a drop, only the tab that kept the
            # code (or one that types it) gets the session back
            fresh = [s for s in open_ if s.page is None and not s.ever_attached]
            if len(open_) == 1 and fresh:
                self._bind(page, fresh[0])
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
        if not proven and not self.throttle.allow(client=page.client.client_id, address=address):
            now = time.monotonic()
            if now - self._throttle_logged > 60.0:
                self._throttle_logged = now
                LOGGER.warning(
                    "join attempts throttled (last from %s%s)",
                    address,
                    "; the server-wide budget is spent: someone may be guessing codes"
                    if self.throttle.saturated()
                    else "",
                )
            page.show_join(
                ask_code=True, on_code=lambda c, p=page: self._join(p, c), notice=JOIN_THROTTLED
            )
            return
        code = normalize_code(typed)
        with self._lock:
            live = self._sessions.get(code)
        if live is None or live.closed or not self._bind(page, live):
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

    def _bind(self, page: ParticipantPage, live: LiveSession) -> bool:
        """Bind ``page`` to ``live`` unless another tab holds it; True when bound."""
        with self._lock:
            if page.client.client_id not in self._pages:
                return True  # the tab closed meanwhile: nothing to tell it
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
        self.firewall.bind(page.client.client_id)
        with self._lock:
            token = self._tokens.get(live.code, "")
        with contextlib.suppress(Exception):  # the tab keeps its token for a reload
            page.run_script(_cookie_script(token))
        return True


def _cookie_script(value: str) -> str:
    """JavaScript that keeps ``value`` in the tab's rejoin cookie (an empty value clears it)."""
    age = REJOIN_KEEP_S if value else 0
    cookie = f"{REJOIN_COOKIE}={value}; path=/; max-age={age}; SameSite=Strict"
    return f"document.cookie = {json.dumps(cookie)};"


def _check_page_is_blind(words: tuple[str, ...]) -> None:
    """Raise :class:`ServerError` when a condition word of the served protocol occurs in the
    participant page's own script or fixed texts (the guard would block them, breaking the page):
    the level must be renamed."""
    fixed = [
        page_script(keys_uuid="", title=PAGE_TITLE),
        link_script(uuid=""),
        JOIN_FAILED,
        JOIN_THROTTLED,
        LINK_CLOSED_TEXT,
        LINK_FAILED_TEXT,
        LINK_INVALID_TEXT,
        LINK_IN_USE_TEXT,
    ]
    found = sorted({w for text in fixed for w in find_words(text, words)})
    if found:
        raise ServerError(
            f"the protocol's condition word(s) {found} occur in the participant page's own"
            " script or texts, which the blinding guard would then block; rename those levels"
        )


def _lan_address() -> str:
    """This machine's address on the LAN (falls back to the host name)."""
    import socket

    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("10.255.255.255", 1))
            return str(s.getsockname()[0])
    except OSError:
        return socket.gethostname()

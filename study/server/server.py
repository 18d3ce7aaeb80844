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
  trial pauses and the session waits for its code again (the tabs:
  :mod:`study.server.participant_tabs`).
* Open enrolment (online studies, off by default): once it is on (or has enrolled anyone), a
  new tab first says what its URL carries, and a tab whose URL carries a recruitment ID
  (``?PROLIFIC_PID=...`` or ``?pid=...``, :mod:`study.server.recruitment`) gets a session
  without a code while the link is on and has places (:mod:`study.server.open_link`); the
  session starts at once. One session per recruitment ID: a reload with the same ID rejoins
  it, another tab with the same ID waits (and is told so) while the first holds it.
* Behind a TLS reverse proxy (``trusted_proxies``), limits and logs use the client address
  the proxy forwards and the ``Origin`` check accepts the public host name it forwards
  (:mod:`study.server.forwarded`).
* A finished session stays while a tab shows its last screen and for a grace after it left (a
  reload gets that screen again), then it is closed and let go: its threads end, its code and
  rejoin cookie work no more, and the console lists it from the store
  (:mod:`study.server.finished_sessions`).
* Experimenter view: a second ``ViserServer`` on ``127.0.0.1`` only, so the participant's
  machine has no route to it. The two servers share nothing but this object.

viser runs callbacks in a thread pool; every registry change happens under ``self._lock``.
"""

from __future__ import annotations

import hmac
import logging
import threading
import time
from collections import deque
from collections.abc import Iterable
from pathlib import Path

from app.warm_up import warm_up
from study.errors import StudyError
from study.protocol.blinding import find_words
from study.server import blinding_guard, firewall, logs, realtime, viser_door
from study.server.console_model import LinkState, SessionDetail, SessionSummary, StudyProgress
from study.server.console_page import ExperimenterConsole
from study.server.finished_sessions import (
    FINISHED_GRACE_S,
    RETIRED_KEPT,
    Retired,
    finished_and_left,
)
from study.server.firewall import LOOPBACK_NAMES
from study.server.forwarded import Network
from study.server.join import JoinThrottle, new_join_code, new_token
from study.server.link_places import LINK_IDLE_S, SWEEP_S, PlaceSweeper, idle_link_sessions
from study.server.listening import ListeningClock
from study.server.live import LiveSession, SessionFactory
from study.server.live.progress import study_progress
from study.server.live.texts import (
    LINK_CLOSED_TEXT,
    LINK_FAILED_TEXT,
    LINK_IN_USE_TEXT,
    LINK_INVALID_TEXT,
)
from study.server.open_link import OpenLink
from study.server.page_head import HEAD, PageHead
from study.server.page_script import page_script
from study.server.participant_tabs import (
    JOIN_FAILED,
    JOIN_THROTTLED,
    PAGE_TITLE,
    ParticipantTabs,
)
from study.server.recruitment import Recruitment, link_script
from study.session import EXPERIMENTER_ACTIONS, FINAL_STATUSES

LOGGER = logging.getLogger("study.server.server")


class ServerError(StudyError, RuntimeError):
    """The study server cannot do what was asked (unknown session code, duplicate ...)."""


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
        link_idle_s: float = LINK_IDLE_S,
        finished_grace_s: float = FINISHED_GRACE_S,
        freeze_heap: bool = True,
    ) -> None:
        """``open_link``: places of the open-enrolment link (0: off; the console turns it on
        and off); ``public_url``: the participants' address as they reach it (behind a
        proxy), shown with the link; ``trusted_proxies``: reverse proxies whose forwarded
        client address and host name count (``study.server.forwarded``); ``port_firewall``:
        the participant port's rules (a default ``Firewall`` if not given; tests and
        benchmarks pass one with other limits); ``log_path``: the server's log file
        (``study.server.logs``), whose disk use the console shows; ``link_idle_s``: how long a
        link session left before consent keeps its place (``study.server.link_places``);
        ``finished_grace_s``: how long a finished session stays once no tab shows it
        (``study.server.finished_sessions``); ``freeze_heap``: collect once, then keep what
        start-up made out of later collections (``study.server.realtime``), as a process that
        serves one study wants; a process that starts many servers one after another (the
        tests) may leave it off: each start's full collection walks the whole process, about
        180 ms at the 420,000 objects of a test worker."""
        self.log_path = log_path
        # the control tick's compiled kernels now, not at a participant's first tick
        LOGGER.info("the control tick's kernels ready in %.2f s", warm_up())
        self.factory = factory
        self.render_hz = render_hz
        self.kiosk = kiosk
        self.throttle = throttle or JoinThrottle()
        self._lock = threading.RLock()
        self._sessions: dict[str, LiveSession] = {}
        self._tokens: dict[str, str] = {}
        """Each session's rejoin token, by join code."""
        self._retired: deque[Retired] = deque(maxlen=RETIRED_KEPT)
        """Finished sessions let go, oldest first (``study.server.finished_sessions``)."""
        self._issued: set[str] = set()
        """Every join code this server has given out: none is given twice, so a finished
        participant who types their old code never joins another's session (a few dozen bytes
        a session). A restart starts afresh: a new code then matches one of 10,000 earlier ones
        at odds of 1 in 15,000 (23^6 codes)."""
        self.tabs = ParticipantTabs(self)
        self.public_url = public_url
        self.open_link = OpenLink(factory.store, enabled=open_link > 0, cap=open_link)
        self.firewall = port_firewall or firewall.Firewall(
            firewall.FirewallConfig(allow_share=allow_share, trusted_proxies=trusted_proxies)
        )
        self._start_participant(host=host, port=port, verbose=verbose, words=condition_words)
        self._start_experimenter(
            host=experimenter_host, port=experimenter_port, verbose=verbose, share=allow_share
        )
        self.console = ExperimenterConsole(self.experimenter, self, refresh_hz=console_refresh_hz)
        self.link_idle_s = link_idle_s
        self.finished_grace_s = finished_grace_s
        shortest = min(link_idle_s, finished_grace_s)
        self._places = PlaceSweeper(
            self._sweep, period_s=min(SWEEP_S, max(0.05, shortest / 4)), name="sweeper"
        )
        self._froze_heap = freeze_heap
        if freeze_heap:
            realtime.freeze_heap()  # after start-up: collections never walk it again

    def _start_experimenter(self, *, host: str, port: int, verbose: bool, share: bool) -> None:
        """The console's viser server: it may use every message type; share links stay off
        unless asked for, and no page of another site open in the experimenter's browser may
        drive it (origin)."""
        self.experimenter_firewall = firewall.Firewall(
            firewall.FirewallConfig(
                allowed=None,
                allow_share=share,
                max_bytes=8 * 2**20,
                rate_per_s=2000.0,
                loopback_only=host in LOOPBACK_NAMES,
                shares_per_s=None,  # the experimenter's own tabs: no shares, never idle-closed
                idle_timeout_s=None,
            )
        )
        self.experimenter = firewall.start_server(
            self.experimenter_firewall, host=host, port=port, verbose=verbose
        )
        firewall.install(self.experimenter, self.experimenter_firewall)

    def _start_participant(
        self, *, host: str, port: int, verbose: bool, words: Iterable[str]
    ) -> None:
        """Start the participant's server behind its firewall and the blinding guard."""
        self.firewall.rejoin_token = self._proven_token
        self.firewall.on_bound_drop = self._bound_input_dropped
        self.firewall.page_filter = PageHead()  # viser's own notices hidden from the first paint
        self.participant = firewall.start_server(
            self.firewall, host=host, port=port, verbose=verbose
        )
        self.listening = ListeningClock(viser_door.event_loop(self.participant))
        """The participant port's loop on time or behind (held keys' silence is counted by it)."""
        self.guard = blinding_guard.install(self.participant, words=words)
        _check_page_is_blind(self.guard.words)
        firewall.install(self.participant, self.firewall)
        self.participant.gui.configure_theme(
            show_share_button=False, show_logo=False, control_width="large"
        )
        self.participant.scene.world_axes.visible = False
        self.participant.on_client_connect(self.tabs.connected)
        self.participant.on_client_disconnect(self.tabs.disconnected)

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

    def stop(self) -> bool:
        """Close every session and stop both ports; returns whether both servers' threads
        ended within ``viser_door.STOP_WAIT_S``."""
        self._places.stop()
        self.console.close()
        with self._lock:
            sessions = list(self._sessions.values())
        for live in sessions:
            live.close()
        # the servers stop first: a message that arrives while they shut down is still screened
        # (a share-link request sent just before stop() reached viser when the order was reversed);
        # only the firewalls' sweepers end before, and the connections no session needs are
        # reset, on the loops that run them (Firewall.before_stop)
        self.firewall.before_stop()
        self.experimenter_firewall.before_stop()
        self.listening.stop()
        ended = viser_door.stop_server(self.participant)
        ended = viser_door.stop_server(self.experimenter) and ended
        blinding_guard.uninstall(self.participant)
        firewall.uninstall(self.participant)
        firewall.uninstall(self.experimenter)
        if self._froze_heap:
            self._froze_heap = False
            realtime.thaw_heap()
        return ended

    # -- sessions ----------------------------------------------------------------------------
    def enrol(self, participant: str, *, recruitment: Recruitment | None = None) -> str:
        """Enrol ``participant`` (or reopen their session) and return its join code."""
        with self._lock:
            for code, live in self._sessions.items():
                if live.participant == participant and not live.closed:
                    return code
            words = self.guard.words
            code = new_join_code(self._issued, avoid=words)
            self._issued.add(code)
            live = self.factory(
                participant,
                code=code,
                title=PAGE_TITLE,
                render_hz=self.render_hz,
                recruitment=recruitment.as_dict() if recruitment else None,
            )
            if recruitment is None and (known := self.open_link.recruitment_of(participant)):
                live.recruitment = known.ids
            live.on_closed = lambda: self.tabs.offer_all()
            self._sessions[code] = live
            self._tokens[code] = new_token(avoid=words)
        LOGGER.info("session %s opened for %s", code, participant)
        self.tabs.offer_all()
        return code

    def reopenable(self) -> list[str]:
        """Unfinished sessions in the store that no live session holds (a restart or crash
        left them): the console can reopen them."""
        with self._lock:
            open_now = {s.participant for s in self._sessions.values() if not s.closed}
        # a link session given back before consent comes back by its link, not the console
        return self.factory.reopenable(open_now=open_now | self.open_link.released())

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
            retired = self._retired_by_code(code)
        if live is None and retired is not None:
            raise ServerError(
                f"the session of {retired.participant} (code {code}) is over and no longer live:"
                " nothing more can be done on it here; its records are in the store"
                " (`python -m study export` writes them out)"
            )
        if live is None:
            raise ServerError(f"no session with join code {code!r}; check the console's list")
        return live

    def _retired_by_code(self, code: str) -> Retired | None:
        return next((r for r in reversed(self._retired) if r.code == code), None)

    def sessions(self) -> list[LiveSession]:
        with self._lock:
            return list(self._sessions.values())

    def open_sessions(self) -> list[LiveSession]:
        return [s for s in self.sessions() if not s.closed]

    # Console protocol ------------------------------------------------------------------------
    def summaries(self) -> list[SessionSummary]:
        """The finished sessions let go (the newest ``RETIRED_KEPT``), then the live ones."""
        with self._lock:
            retired = [r.summary for r in self._retired]
        return retired + [s.summary() for s in self.sessions()]

    def detail(self, code: str) -> SessionDetail | None:
        with self._lock:
            live = self._sessions.get(code)
            retired = None if live is not None else self._retired_by_code(code)
        if live is not None:
            return live.detail()
        if retired is not None:
            return retired.detail(self.factory.store, self.factory.protocol)
        return None

    def health(self) -> str:
        """One line for the console: the participant port's tabs and refusals, the log's size."""
        fw = self.firewall
        tabs, bound = self.tabs.counts()
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
        self.tabs.offer_all()
        return result

    def progress(self) -> StudyProgress:
        return study_progress(self.factory.store, self.factory.protocol)

    def link(self) -> LinkState:
        return LinkState(
            enabled=self.open_link.enabled,
            cap=self.open_link.cap,
            used=self.open_link.used(),
            url=self.link_url(),
            refused=tuple(self.open_link.refused.items()),
        )

    def set_link(self, *, enabled: bool, cap: int) -> LinkState:
        self.open_link.configure(enabled=enabled, cap=cap)
        LOGGER.info("open link %s (%d places)", "on" if enabled else "off", cap)
        return self.link()

    # -- participant tabs ----------------------------------------------------------------------
    def find(self, code: str) -> LiveSession | None:
        """The session of join code ``code`` (``None``: none); takes no lock."""
        return self._sessions.get(code)

    def session_token(self, code: str) -> str:
        """The rejoin token of session ``code`` ("" if it has none)."""
        return self._tokens.get(code, "")

    def by_link(self, code: str) -> bool:
        """Whether session ``code`` came by the open link (its tabs come back by their URL)."""
        live = self._sessions.get(code)
        return live is not None and bool(live.recruitment)

    def _proven_token(self, value: str) -> str | None:
        """``value`` (a tab's rejoin cookie) when it is the token of a session here (open, or
        finished and not yet let go: a reload gets its last screen), else ``None`` (the
        firewall asks at the door)."""
        return value if self.code_of(value, finished=True) is not None else None

    def code_of(self, token: str | None, *, finished: bool = False) -> str | None:
        """The open session whose rejoin token is ``token`` (compared in constant time); with
        ``finished``, a finished one not yet let go too."""
        if not token:
            return None
        # no lock: the firewall asks from the event loop, which must never wait for an
        # enrolment (the server's lock is held while a session is built); a dict copy is atomic
        tokens = self._tokens.copy()
        for code, expected in tokens.items():
            if hmac.compare_digest(token.encode(), expected.encode()):
                live = self._sessions.get(code)
                return code if live is not None and (finished or not live.closed) else None
        return None

    def _bound_input_dropped(self, client_id: int, reason: str) -> None:
        """The firewall refused a message of a session's tab (on the event loop): the session
        records it (from its own worker thread)."""
        code = self.tabs.session_code(client_id)  # no lock: on the event loop (see code_of)
        live = self._sessions.get(code) if code is not None else None
        if live is not None:
            live.input.dropped(reason)

    def link_session(
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
            live = self._sessions[self.enrol(participant)]
            if participant in self.open_link.released():
                self.open_link.returned(participant)
                live.note_retaken()
            return live, ""

    def _sweep(self) -> None:
        """The sweeper's round: idle link places back, finished sessions let go (the second
        even when the first fails; the sweeper logs what was raised)."""
        try:
            self.reclaim_link_places()
        finally:
            self.drop_finished()

    def drop_finished(self, *, now: float | None = None) -> list[str]:
        """Close and let go the sessions over for ``finished_grace_s`` with no tab on their
        last screen (``study.server.finished_sessions``); returns their participants. ``now``
        (``time.monotonic()``) for tests."""
        now = time.monotonic() if now is None else now
        dropped = []
        for live in finished_and_left(self.sessions(), grace_s=self.finished_grace_s, now=now):
            record = Retired.of(live)  # its row, read before the lock (the store)
            with self._lock:  # a tab that binds meanwhile (a reload) keeps the session
                if live.page is not None or self.tabs.holds(live.code):
                    continue
                self._sessions.pop(live.code, None)
                self._tokens.pop(live.code, None)
                self._retired.append(record)
            live.close()
            dropped.append(live.participant)
        if dropped:
            LOGGER.info(
                "%d finished session(s) let go (no tab on their last screen for %.0f s)",
                len(dropped),
                self.finished_grace_s,
            )
        return dropped

    def reclaim_link_places(self) -> list[str]:
        """Close the open link's sessions left before consent for ``link_idle_s`` and give
        their places back (``study.server.link_places``); returns their participants."""
        now = time.monotonic()
        idle = idle_link_sessions(self.sessions(), idle_s=self.link_idle_s, now=now)
        reclaimed = []
        for live in idle:
            with self._lock:  # a tab that binds meanwhile keeps the session
                if live.page is not None or self.tabs.holds(live.code):
                    continue
                self._sessions.pop(live.code, None)
                self._tokens.pop(live.code, None)
            live.note_released(live.unattended_s(now))
            live.close()
            self.open_link.release(live.participant)
            reclaimed.append(live.participant)
        if reclaimed:
            LOGGER.info(
                "open link: %d place(s) given back (sessions left before consent for %.0f s)",
                len(reclaimed),
                self.link_idle_s,
            )
            self.tabs.offer_all()
        return reclaimed


def _check_page_is_blind(words: tuple[str, ...]) -> None:
    """Raise :class:`ServerError` when a condition word of the served protocol occurs in the
    participant page's own script or fixed texts (the guard would block them, breaking the page):
    the level must be renamed."""
    fixed = [
        HEAD,
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

"""The study server: two viser servers in one process and the registry of live sessions.

* Participant view: a ``ViserServer`` on the LAN (``0.0.0.0``), guarded by the blinding guard.
  A tab that connects is offered a session: none running -> it waits; one -> it binds to it;
  several -> the participant types the join code the experimenter's console shows. A session
  is bound to one tab at a time: a second tab is refused (and the refusal logged as an
  event); when the bound tab goes away (reload, lost connection) its running trial pauses
  and a tab that connects next binds again.
* Experimenter view: a second ``ViserServer`` on ``127.0.0.1`` only, so the participant's
  machine has no route to it. The two servers share nothing but this object.

viser runs callbacks in a thread pool; every registry change happens under ``self._lock``.
"""

from __future__ import annotations

import logging
import secrets
import threading

import viser

from app.ui import blinding
from app.ui.experimenter import ACTIONS, ExperimenterConsole, SessionDetail, SessionSummary
from app.ui.live import LiveSession, SessionFactory
from app.ui.participant import ParticipantPage
from app.ui.scene import frame_task

LOGGER = logging.getLogger("app.ui.server")

PAGE_TITLE = "Robot arm study"


class ServerError(RuntimeError):
    """The study server cannot do what was asked (unknown session code, duplicate ...)."""


def new_join_code(taken: set[str]) -> str:
    """A 4-digit code not in ``taken`` (digits only: nothing a participant could read into)."""
    while True:
        code = f"{secrets.randbelow(9000) + 1000}"
        if code not in taken:
            return code


class StudyServer:
    """Owns the participant and experimenter ``ViserServer``s and the live sessions."""

    def __init__(
        self,
        factory: SessionFactory,
        *,
        host: str = "0.0.0.0",
        port: int = 8080,
        experimenter_host: str = "127.0.0.1",
        experimenter_port: int = 8081,
        render_hz: float = 60.0,
        verbose: bool = False,
        console_refresh_hz: float = 5.0,
    ) -> None:
        self.factory = factory
        self.render_hz = render_hz
        self._lock = threading.RLock()
        self._sessions: dict[str, LiveSession] = {}
        self._pages: dict[int, ParticipantPage] = {}
        self._page_session: dict[int, str] = {}

        self.participant = viser.ViserServer(host=host, port=port, verbose=verbose)
        self.guard = blinding.install(self.participant)
        self.participant.gui.configure_theme(show_share_button=False, control_width="large")
        self.participant.scene.world_axes.visible = False
        self.participant.on_client_connect(self._participant_connected)
        self.participant.on_client_disconnect(self._participant_disconnected)

        self.experimenter = viser.ViserServer(
            host=experimenter_host, port=experimenter_port, verbose=verbose
        )
        self.console = ExperimenterConsole(self.experimenter, self, refresh_hz=console_refresh_hz)

    # -- addresses ---------------------------------------------------------------------------
    @property
    def participant_port(self) -> int:
        return self.participant.get_port()

    @property
    def experimenter_port(self) -> int:
        return self.experimenter.get_port()

    def urls(self, *, lan_host: str | None = None) -> tuple[str, str]:
        host = lan_host or self.participant.get_host()
        if host in ("0.0.0.0", ""):
            host = _lan_address()
        return (
            f"http://{host}:{self.participant_port}",
            f"http://127.0.0.1:{self.experimenter_port}",
        )

    def stop(self) -> None:
        self.console.close()
        with self._lock:
            sessions = list(self._sessions.values())
        for live in sessions:
            live.close()
        blinding.uninstall(self.participant)
        self.participant.stop()
        self.experimenter.stop()

    # -- sessions ----------------------------------------------------------------------------
    def enrol(self, participant: str) -> str:
        """Enrol ``participant`` (or reopen their session) and return its join code."""
        with self._lock:
            for code, live in self._sessions.items():
                if live.participant == participant and not live.closed:
                    return code
            code = new_join_code(set(self._sessions))
            live = self.factory(participant, code=code, title=PAGE_TITLE, render_hz=self.render_hz)
            live.on_closed = lambda: self._offer_all()
            self._sessions[code] = live
        LOGGER.info("session %s opened for %s", code, participant)
        self._offer_all()
        return code

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

    def act(self, code: str, action: str, *, reason: str = "") -> str:
        if action not in ACTIONS:
            raise ServerError(f"unknown action {action!r}; actions: {', '.join(ACTIONS)}")
        result = self.session(code).act(action, reason=reason)
        self._offer_all()
        return result

    # -- participant tabs ----------------------------------------------------------------------
    def _participant_connected(self, client: viser.ClientHandle) -> None:
        page = ParticipantPage(client, title=PAGE_TITLE)
        frame_task(client.camera, look_at=(0.45, 0.0, 0.15))
        with self._lock:
            self._pages[client.client_id] = page
        self._offer(page)

    def _participant_disconnected(self, client: viser.ClientHandle) -> None:
        with self._lock:
            page = self._pages.pop(client.client_id, None)
            code = self._page_session.pop(client.client_id, None)
            live = self._sessions.get(code) if code is not None else None
        if live is not None and page is not None:
            live.detach(page)
        self._offer_all()

    def _offer_all(self) -> None:
        with self._lock:
            pages = [p for cid, p in self._pages.items() if cid not in self._page_session]
        for page in pages:
            self._offer(page)

    def _offer(self, page: ParticipantPage) -> None:
        """Bind ``page`` to the one open session, or ask for a code, or make it wait."""
        with self._lock:
            if page.client.client_id in self._page_session:
                return
            open_ = self.open_sessions()
        if len(open_) == 1:
            self._bind(page, open_[0])
        elif not open_:
            if page.screen_name != "join" or page.asks_code:
                page.show_join(ask_code=False, on_code=lambda _c: None)
        elif page.screen_name != "join" or not page.asks_code:
            page.show_join(ask_code=True, on_code=lambda code, p=page: self._join(p, code))

    def _join(self, page: ParticipantPage, code: str) -> None:
        with self._lock:
            live = self._sessions.get(code)
        if live is None or live.closed:
            page.reject(f"unknown join code {code!r}")
            return
        self._bind(page, live)

    def _bind(self, page: ParticipantPage, live: LiveSession) -> None:
        with self._lock:
            if page.client.client_id not in self._pages:
                return  # the tab closed meanwhile
            if live.page is not None and live.page is not page:
                refused = True
            else:
                refused = False
                self._page_session[page.client.client_id] = live.code
        if refused:
            live.refuse(page)
            return
        live.attach(page)


def _lan_address() -> str:
    """This machine's address on the LAN (falls back to the host name)."""
    import socket

    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("10.255.255.255", 1))
            return str(s.getsockname()[0])
    except OSError:
        return socket.gethostname()

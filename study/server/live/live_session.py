"""``LiveSession``: one study session served to one participant tab at a time.

``study.session.Session`` decides what happens (the state machine, the store, whether the
session is paused); this object connects it to the browser and to time, through its parts:

* the page thread renders the session's blind ``Screen`` on the bound tab whenever the session
  changes (a listener wakes it; ``screens.show_screen``) and turns clicks into session calls;
  bad input is rejected with a message, never raised into viser;
* while a trial runs, a ``PacedLoop`` ticks the session's ``TrialRun`` at the protocol's control
  rate, and the render loop (``view.LiveView``) sends the scene to the tab from snapshots of
  the bodies' poses taken after each tick;
* a lost tab pauses the running trial (``Session.pause(cause="tab_lost")``) and the
  participant resumes it from the next tab with "Continue";
* any pause freezes the participant's input and hides the handle (``controls.LiveInput``);
* an exception in a control tick holds the trial (``control_faults.ControlFaults``), is recorded and
  shown to the experimenter, and the page asks to wait: the loop never dies silently;
* each run ends with a neutral outcome sentence (``texts``); the console reads ``console``.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from typing import Any

from app.robot import Simulation, build_scene
from app.teleop.participant_input import ParticipantInput
from study.server.console_model import SessionDetail, SessionSummary
from study.server.live.console import LiveFacts, LivePlots, session_detail, session_summary
from study.server.live.control_faults import ControlFaults
from study.server.live.controls import LiveInput
from study.server.live.experimenter_control import ExperimenterControl
from study.server.live.live_run import LiveRun
from study.server.live.screens import show_screen
from study.server.live.texts import RUN_FINISHED
from study.server.live.timeline import started_at
from study.server.live.view import LiveView, shows_intent
from study.server.loop import PacedLoop
from study.server.open_link import RELEASED, RETAKEN
from study.server.page_scene import SceneView
from study.server.participant_page import ParticipantPage, message_screen
from study.session import (
    FINAL_STATUSES,
    Session,
    SessionClosedError,
    TrialRun,
)

LOGGER = logging.getLogger("study.server.live")

PAGE_STOP_S = 2.0
"""How long ``close`` waits for the page thread to end (it wakes at once; a screen being built
on a slow tab may hold it that long)."""


class LiveSession:
    """A ``study.session.Session`` served to one participant tab at a time."""

    def __init__(self, session: Session, *, code: str, title: str, render_hz: float = 60.0):
        self.session = session
        self.participant = session.participant
        self.code = code
        self.title = title
        self.page: ParticipantPage | None = None
        self.ever_attached = False
        """A tab has held this session (a kiosk then asks for the code after a drop)."""
        self._unattended_since: float | None = time.monotonic()
        """Since when no tab holds this session (``None`` while one does)."""
        self._finished_at: float | None = None
        """When (monotonic) the page thread found the session over and released it."""
        self.ended_at: datetime | None = None
        """When the session was over (the console's session time stops there)."""
        self.on_closed: Callable[[], None] | None = None
        self.recruitment: tuple[tuple[str, str], ...] = ()
        """The recruitment IDs the participant came with (open enrolment), for the console."""
        self._started_at: datetime | None = None
        self._start_lookup = 0.0
        self.log: deque[str] = deque(maxlen=20)
        self._lock = threading.RLock()
        """The current run, its trial, the input and the view against the page thread, viser
        callbacks and the console (``study.session`` gives the lock order)."""
        self._shown: tuple[object, ...] | None = None
        self._dirty = threading.Event()
        """Set when the page may need redrawing (the page thread waits on it)."""
        self._stop = threading.Event()
        self.input = LiveInput(code=code, record=self._event)
        self.view = LiveView(code=code, render_hz=render_hz, tab=self._tab)
        self.faults = ControlFaults(code=code, record=self._event)
        self.plots = LivePlots()
        self.trial_run = LiveRun(
            session=session,
            code=code,
            view=self.view,
            input=self.input,
            faults=self.faults,
            plots=self.plots,
            page=lambda: self.page,
            redraw=self._redraw,
        )
        self.experimenter = ExperimenterControl(
            session=session,
            faults=self.faults,
            input=self.input,
            tab=lambda: (self.page, self.trial_run.run),
            wake=self._dirty.set,
        )
        self._closed_notified = False
        session.add_listener(lambda _screen: self._dirty.set())
        self._page_thread = threading.Thread(
            target=self._page_loop, name=f"page-{code}", daemon=True
        )
        self._page_thread.start()

    # -- state ---------------------------------------------------------------------------------
    @property
    def closed(self) -> bool:
        """True once the session is completed, withdrawn or ended (no tab binds to it)."""
        return self.session.finished

    @property
    def run(self) -> TrialRun | None:
        """The current (or last) run of this live session."""
        return self.trial_run.run

    @property
    def fault(self) -> str | None:
        return self.faults.fault

    @property
    def control_loop(self) -> PacedLoop | None:
        return self.trial_run.control

    @property
    def participant_input(self) -> ParticipantInput | None:
        return self.input.source

    @property
    def scene_view(self) -> SceneView | None:
        return self.view.view

    def _redraw(self) -> None:
        self._shown = None
        self._dirty.set()

    def _tab(self) -> tuple[ParticipantPage | None, ParticipantInput | None]:
        return self.page, self.input.source

    def _event(self, kind: str, detail: Mapping[str, Any]) -> bool:
        """Append an event to the session's log (UI events: tabs, refusals, rejected input),
        through ``Session.record_event``: written only while this process holds the lease.
        False when the store refused it (it is in the server log then), or when the session is
        over and released (a tab on its last screen: the console's log only)."""
        where = detail.get("address")
        self.log.append(f"{time.strftime('%H:%M:%S')} {kind}" + (f" ({where})" if where else ""))
        if self._stop.is_set() or self._finished_at is not None:
            return False  # shutting down (the store may be closed), or over and released
        try:
            self.session.record_event(kind, detail)
        except SessionClosedError as exc:
            # finished and released, or taken over by another process: not ours to log into
            over = self.session.status in FINAL_STATUSES
            LOGGER.info("event %s not recorded: %s", kind, "the session is over" if over else exc)
            return False
        except Exception:
            LOGGER.exception("could not record event %s", kind)
            return False
        return True

    # -- tabs ----------------------------------------------------------------------------------
    def attach(self, page: ParticipantPage) -> None:
        page.on_reject = lambda problem: self._event("input_rejected", {"problem": problem[:200]})
        page.on_keys = lambda down, up: self.input.on_keys(down, up, reframe=self.reframe)
        with self._lock:
            self.page = page
            self.ever_attached = True
            self._unattended_since = None
            self._shown = None
        self._event(
            "participant_connected",
            {"client": page.client.client_id, "address": getattr(page, "address", "unknown")},
        )
        with self._lock:
            if self.trial_run.running:
                self.trial_run.show_scene(page)
        self._dirty.set()

    def detach(self, page: ParticipantPage) -> None:
        with self._lock:
            if self.page is not page:
                return
            self.page = None
            self._unattended_since = time.monotonic()
            self.view.drop()
            running = self.trial_run.running
        self._event("participant_disconnected", {"client": page.client.client_id})
        if running and not self.session.finished:
            self.input.freeze(None)
            try:
                if not self.session.paused:
                    self.session.pause(cause="tab_lost")
            except Exception as exc:
                LOGGER.warning("could not pause after disconnect: %s", exc)

    def unattended_s(self, now: float) -> float:
        """Seconds until ``now`` (``time.monotonic()``) that no tab has held this session (0
        while one holds it)."""
        since = self._unattended_since
        return 0.0 if since is None else max(0.0, now - since)

    def over_and_left_s(self, now: float) -> float | None:
        """Seconds until ``now`` (``time.monotonic()``) that this session has been over with no
        tab on its last screen: since it was over or since its last tab left, whichever came
        later; ``None`` while it is not over (or not released yet) or a tab holds it."""
        over, since = self._finished_at, self._unattended_since
        if over is None or since is None:
            return None
        return max(0.0, now - max(over, since))

    def note_released(self, idle_s: float) -> None:
        """Record that the open link took this session's place back (``link_places``)."""
        self._event(RELEASED, {"unattended_s": round(idle_s)})

    def note_retaken(self) -> None:
        """Record that this session's recruitment ID came back after its place was given back."""
        self._event(RETAKEN, {})

    def note_refused_join(self, page: ParticipantPage) -> None:
        """The right code from a second tab while one holds the session: logged for the
        experimenter; the tab is told only that the code did not work."""
        self._event(
            "second_tab_refused",
            {"client": page.client.client_id, "address": getattr(page, "address", "unknown")},
        )

    # -- what the page's buttons call (``screens.PageHandlers``) --------------------------------------
    def _participant(self, action: str, call: Callable[[], object]) -> None:
        page = self.page
        try:
            call()
        except Exception as exc:  # a stale click or bad answer: tell, log, keep running
            if page is not None:
                page.reject(f"{action}: {exc}")
            else:
                self._event("input_rejected", {"problem": f"{action}: {exc}"[:200]})
            self._shown = None  # redraw: the screen's buttons were disabled by the click
            self._dirty.set()

    def agree(self) -> None:
        self._participant("agree", self.session.agree)

    def decline(self) -> None:
        reason = "participant declined consent"
        self._participant("decline", lambda: self.session.withdraw(reason=reason))

    def start_trial(self) -> None:
        def start() -> None:
            with self._lock:
                if self.trial_run.running:
                    return
                # the condition's mapping: [control]'s, unless a level (say a between-subjects
                # input factor) sets it
                mapping = str(self.session.trial_config().extra["input_mapping"])
                source = ParticipantInput(mapping=mapping)
                run = self.session.start_trial(input_source=source)
                self.trial_run.begin(run, source)

        self._participant("start_trial", start)

    def answer(self, answers: Mapping[str, object]) -> None:
        self._participant("answer", lambda: self.session.answer(answers))

    def finish(self) -> None:
        self._participant("finish", self.session.finish)

    def continue_after_tab_lost(self) -> None:
        self._participant("resume", self.session.resume)

    def seen_outcome(self) -> None:
        self.trial_run.outcome = None
        self._dirty.set()

    def grasp(self) -> None:
        self.input.grasp()

    def reframe(self) -> None:
        """Put the tab's camera back on the task view."""
        self.view.reframe(self.page)

    def preview(self, page: ParticipantPage) -> None:
        """Show the next trial's scene at its start state on the ready screen, so the browser
        has loaded it (the first draw is slow in software WebGL) before the trial's clock runs."""
        try:
            config = self.session.trial_config()
        except Exception:  # not on a trial step any more
            return
        scene = build_scene(config.scene)
        sim = Simulation(scene, physics_dt=config.physics_dt)
        with self._lock:
            if self.trial_run.running:
                return  # Start was pressed meanwhile: the run's own frames show
            self.view.draw_preview(
                page, scene, sim.model, sim.poses(), intent=shows_intent(config.extra)
            )

    def time_left(self) -> float | None:
        """Seconds left in the running run (its trial time: pauses excluded), else None."""
        run = self.trial_run.run
        if run is None or run.over:
            return None
        return run.config.time_limit_s - run.trial.t

    def _end_run(self, run: TrialRun) -> None:
        """Stop ``run``'s ticking and tell its outcome -- unless another run has begun since the
        page thread saw ``run`` over (Start pressed meanwhile: ending "the current run" then
        stopped the new run's ticks after one or two, and it froze until the experimenter
        stepped in)."""
        with self._lock:
            if self.trial_run.run is not run:
                return  # its control loop ended with it; the new run's begin replaced the rest
            page = self.page
            self.trial_run.end()
            outcome = self.trial_run.outcome
        if page is not None:
            page.remove_gizmo()
            self.view.clear_notices(page)
            if outcome is not None:  # said over the scene too: a drag may have been cut short
                page.notify(outcome, seconds=6.0, screen=message_screen(RUN_FINISHED))

    # -- the page --------------------------------------------------------------------------------
    def _page_loop(self) -> None:
        while not self._stop.is_set():
            self._dirty.wait(timeout=0.25)
            self._dirty.clear()
            if self._stop.is_set():
                return
            try:
                self._sync()
            except Exception:
                LOGGER.exception("session %s: page update failed", self.code)

    def _sync(self) -> None:
        run = self.trial_run.run
        if run is not None and run.over and self.trial_run.control is not None:
            self._end_run(run)
        if self.closed and not self._closed_notified:
            self._closed_notified = True
            self.ended_at = datetime.now(UTC)
            self.view.stop()
            with contextlib.suppress(Exception):
                self.session.close()  # release the lease; the record stays readable
            self._finished_at = time.monotonic()
            if self.on_closed is not None:
                self.on_closed()
        if run is not None and not run.over:
            held = run.paused or self.faults.held
            if held and not self.input.frozen:
                self.input.freeze(self.page)
            elif (
                not held and self.input.frozen and (gripper := self.trial_run.gripper()) is not None
            ):
                trial = self.trial_run.trial
                reach = None if trial is None else trial.scene.reach
                self.input.thaw(self.page, gripper, reach=reach)
        page = self.page
        if page is None:
            return
        screen = self.session.screen()
        paused_by = self.session.paused_by
        key = (
            page.client.client_id,
            screen.revision,
            paused_by,
            screen.paused,
            self.faults.held,
            self.trial_run.outcome,
        )
        if key == self._shown:
            return
        show_screen(
            page,
            screen,
            fault=self.faults.held,
            paused_by=paused_by,
            outcome=self.trial_run.outcome,
            agree_label=self.session.protocol.texts.consent_agree or "I agree",
            handlers=self,
            status=self.session.status,
            texts=self.session.texts,  # the online debrief for a participant by the open link
        )
        self._shown = key  # only once shown: a screen that failed is tried again

    # -- experimenter --------------------------------------------------------------------------
    def act(self, action: str, *, reason: str = "") -> str:
        """Run an experimenter action; returns a line for the console (errors raise)."""
        return self.experimenter.act(action, reason=reason)

    def _facts(self) -> LiveFacts:
        return LiveFacts(
            code=self.code,
            connected=self.page is not None,
            started_at=self.started_at(),
            run=self.trial_run.run,
            log=tuple(self.log),
            fault=self.faults.fault,
            recruitment=self.recruitment,
            ended_at=self.ended_at,
        )

    def started_at(self) -> datetime | None:
        """When the session was first started (its first ``start`` event; looked up in the
        store at most once a second until it has one)."""
        if self._started_at is None and time.monotonic() >= self._start_lookup:
            self._start_lookup = time.monotonic() + 1.0
            with contextlib.suppress(Exception):
                events = self.session.store.events(session_id=self.session.session_id)
                self._started_at = started_at(events)
        return self._started_at

    def summary(self) -> SessionSummary:
        return session_summary(self.session, self._facts())

    def detail(self) -> SessionDetail:
        return session_detail(self.session, self._facts(), self.plots)

    def close(self) -> None:
        """Stop the threads (the page thread too, within ``PAGE_STOP_S``) and release the
        session (a running trial is marked interrupted)."""
        self._stop.set()
        self._dirty.set()
        self.trial_run.stop()
        self.view.stop()
        self.input.close()
        with contextlib.suppress(Exception):
            self.session.close()
        if self._page_thread is not threading.current_thread():
            self._page_thread.join(PAGE_STOP_S)

"""One live study session on the server: the session engine, its participant tab, its threads.

``study.session.Session`` decides what happens (the state machine, the store); this object
connects it to the browser and to time:

* it renders the session's blind ``Screen`` on the bound participant tab whenever the session
  changes (a listener wakes a page thread), and turns clicks into session calls (agree, start
  trial, answers, finish); bad input is rejected with a message, never raised into viser;
* while a trial runs, a :class:`~study.server.loop.PacedLoop` ticks the session's ``TrialRun`` at
  the protocol's control rate in its own thread, and a second loop sends the scene to the
  tab at up to ``render_hz`` from snapshots of the simulation taken after each tick;
* a lost tab pauses the running trial (a ``pause`` event, the paused time excluded from the
  trial's time) and the participant resumes it from the next tab with "Continue";
* any pause (experimenter, lost tab, fault) freezes the participant's input and hides the
  handle; on resume the target is the gripper and the handle is back on it;
* an exception in a control tick (a full disk included) holds the trial, is recorded as a
  ``control_fault`` event and shown to the experimenter, and the page asks to wait: the loop
  never dies silently;
* the scene is sent only when something moved, and only the current run's poses (never an
  earlier run's on the next ready screen); each run ends with a neutral outcome sentence.
"""

from __future__ import annotations

import contextlib
import logging
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from app.teleop.errors import TeleopError
from app.teleop.keyboard import KEYMAP
from app.trial.events import EventKind, TrialEvent
from study.server.experimenter import SessionDetail, SessionSummary
from study.server.inputs import InputFrozen, ParticipantInput
from study.server.intent_cue import IntentGoals, ring_opacity
from study.server.loop import PacedLoop
from study.server.participant import LikertItem, ParticipantPage
from study.server.scene import SceneView, frame_scene

LOGGER = logging.getLogger("study.server.live")

PLOT_WINDOW = 1500
"""Ticks kept for the console's live plots (15 s at 100 Hz)."""

PARTICIPANT_ACTIONS = ("agree", "start_trial", "answer", "finish")

MOVED_M = 2e-4
"""Bodies that moved less than this (m; rotation-matrix entries by 10x this) since the last
frame sent are not re-sent: an arm holding still, which jitters by micrometres under its
controller, sends no scene updates (0.2 mm is a tenth of a pixel at the task view)."""

OUTCOME_SENTENCES: dict[str, str] = {
    "success": "You lifted the {target}.",
    "wrong_object": "You lifted the other object, not the {target}.",
    "dropped": "The object slipped out of the gripper.",
    "timeout": "Time is up.",
}
"""What the participant reads after a run, ``{target}`` being the object asked for (the
instructions name it already): how the run ended, never a condition."""
ENDED_BY_EXPERIMENTER = "The experimenter ended this run."
MISSED_GRASP = "Nothing to grasp there: bring the gripper around the object, then close it."

WAIT_TEXT = "Please wait a moment: the experimenter will continue the session."


class LiveSession:
    """A ``study.session.Session`` served to one participant tab at a time."""

    def __init__(self, session: Any, *, code: str, title: str, render_hz: float = 60.0) -> None:
        self.session = session
        self.participant: str = session.participant
        self.code = code
        self.title = title
        self.render_hz = render_hz
        self.page: ParticipantPage | None = None
        self.ever_attached = False
        """A tab has held this session (a kiosk then asks for the code after a drop)."""
        self.on_closed: Callable[[], None] | None = None
        self.opened_at = time.monotonic()
        self.log: deque[str] = deque(maxlen=20)
        self._lock = threading.RLock()
        self._disconnect_paused = False
        self._shown: tuple[Any, ...] | None = None
        # trial machinery
        self._run: Any = None
        self._input: ParticipantInput | None = None
        self._control: PacedLoop | None = None
        self._render: PacedLoop | None = None
        self._view: SceneView | None = None
        self._view_key: tuple[int, str, bool] | None = None
        self._view_scene: Any = None
        # (run key, seq, xpos, xmat) after the last tick that moved something; the render loop
        # sends it only while the view shows that run (``_frame_key``), never an old run's pose
        # ... and the robot's intent (predicted goal, confidence), None before the first tick
        self._snapshot: (
            tuple[object, int, np.ndarray, np.ndarray, np.ndarray, tuple[int, float] | None] | None
        ) = None
        self._frame_key: object = None
        self._rendered_seq = -1
        self.fault: str | None = None
        """The last control-loop error, shown to the experimenter until they resume."""
        self._outcome: str | None = None
        self._input_paused = False
        self._render_lock = threading.Lock()
        self._unrecorded_fault: dict[str, Any] | None = None
        self._missed_grasp = threading.Event()
        self._writer_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"events-{code}")
        self._plot_lock = threading.Lock()
        self._plot: deque[tuple[float, float, float, np.ndarray]] = deque(maxlen=PLOT_WINDOW)
        self.goal_names: tuple[str, ...] = ()
        # page thread: re-render on every session change
        self._dirty = threading.Event()
        self._stop = threading.Event()
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
        return bool(self.session.finished)

    @property
    def control_loop(self) -> PacedLoop | None:
        return self._control

    @property
    def participant_input(self) -> ParticipantInput | None:
        return self._input

    @property
    def scene_view(self) -> SceneView | None:
        return self._view

    def _event(self, kind: str, detail: Mapping[str, Any]) -> bool:
        """Append an event to the session's log (UI events: tabs, refusals, rejected input),
        through ``Session.record_event``: written only while this process holds the lease.
        False when the store refused it (it is in the server log then)."""
        from study.session import SessionClosedError

        where = detail.get("address")
        self.log.append(f"{time.strftime('%H:%M:%S')} {kind}" + (f" ({where})" if where else ""))
        if self._stop.is_set():
            return False  # shutting down: the store may already be closed
        try:
            self.session.record_event(kind, detail)
        except SessionClosedError as exc:
            # finished and released, or taken over by another process: not ours to log into
            LOGGER.info("event %s not recorded: %s", kind, exc)
            return False
        except Exception:
            LOGGER.exception("could not record event %s", kind)
            return False
        return True

    # -- tabs ----------------------------------------------------------------------------------
    def attach(self, page: ParticipantPage) -> None:
        page.on_reject = lambda problem: self._event("input_rejected", {"problem": problem[:200]})
        page.on_keys = self._on_keys
        with self._lock:
            self.page = page
            self.ever_attached = True
            self._shown = None
        self._event(
            "participant_connected",
            {"client": page.client.client_id, "address": getattr(page, "address", "unknown")},
        )
        with self._lock:
            if self._run is not None and not self._run.over:
                self._show_trial_scene(page)
        self._dirty.set()

    def detach(self, page: ParticipantPage) -> None:
        with self._lock:
            if self.page is not page:
                return
            self.page = None
            self._view = None
            self._view_key = None
            run = self._run
            running = run is not None and not run.over
        self._event("participant_disconnected", {"client": page.client.client_id})
        if running and not self.session.finished:
            self._pause_input()
            try:
                if not run.paused:
                    self.session.pause()
                    self._disconnect_paused = True
            except Exception as exc:
                LOGGER.warning("could not pause after disconnect: %s", exc)

    def note_refused_join(self, page: ParticipantPage) -> None:
        """The right code from a second tab while one holds the session: logged for the
        experimenter; the tab is told only that the code did not work."""
        self._event(
            "second_tab_refused",
            {"client": page.client.client_id, "address": getattr(page, "address", "unknown")},
        )

    # -- participant actions -------------------------------------------------------------------
    def _participant(self, action: str, call: Callable[[], Any]) -> None:
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

    def _start_trial(self) -> None:
        def start() -> None:
            with self._lock:
                if self._run is not None and not self._run.over:
                    return
                source = ParticipantInput()
                run = self.session.start_trial(input_source=source)
                self._begin_run(run, source)

        self._participant("start_trial", start)

    def _answer(self, answers: dict[str, int]) -> None:
        self._participant("answer", lambda: self.session.answer(answers))

    def _continue_after_disconnect(self) -> None:
        def resume() -> None:
            self._disconnect_paused = False
            self.session.resume()

        self._participant("resume", resume)

    def _refused(self, exc: Exception) -> None:
        """An input that arrived while paused: logged (rate-limited by the session), not shown.
        Written from one worker thread: input callbacks run on viser's event loop, which a
        store write must never hold up."""
        problem = str(exc)[:200]
        with contextlib.suppress(RuntimeError):  # closing: the worker is gone
            self._writer_pool.submit(self._event, "input_rejected", {"problem": problem})

    def _grasp(self) -> None:
        source = self._input
        if source is None:
            return
        try:
            source.request_grasp()
        except InputFrozen as exc:
            self._refused(exc)

    def _on_target(self, target: np.ndarray) -> None:
        source = self._input
        if source is None:
            return
        try:
            source.set_target(target)
        except InputFrozen as exc:
            self._refused(exc)
        except TeleopError as exc:
            self._refused(exc)

    def _on_keys(self, down: frozenset[str], up: frozenset[str]) -> None:
        """Key-state changes from the page: steering keys to the input, G grasps, V re-frames."""
        source = self._input
        if source is not None:
            for key in up & set(KEYMAP):
                source.key_up(key)
        if "v" in down:
            self._reframe()
        if source is None:
            return
        for key in sorted(down):
            try:
                if key == "g":
                    source.request_grasp()
                elif key in KEYMAP:
                    source.key_down(key)
            except InputFrozen as exc:
                self._refused(exc)

    def _reframe(self) -> None:
        """Put the tab's camera back on the task view."""
        page, view_scene = self.page, self._view_scene
        if page is not None and view_scene is not None:
            frame_scene(page.client.camera, view_scene)

    def _pause_input(self) -> None:
        """Freeze the participant's input and hide the handle (idempotent)."""
        self._input_paused = True
        source, page = self._input, self.page
        if source is not None:
            source.freeze()
        if page is not None:
            page.show_gizmo(False)

    def _resume_input(self) -> None:
        """Thaw the input with the target at the gripper, the handle back on it and shown."""
        run, source, page = self._run, self._input, self.page
        self._input_paused = False
        if run is None or source is None or run.over:
            return
        gripper = np.asarray(run.trial.sim.ee, float)
        source.thaw()
        try:
            source.set_target(gripper)
        except (InputFrozen, TeleopError):
            LOGGER.debug("could not put the target on the gripper", exc_info=True)
        if page is not None:
            page.move_gizmo(gripper)
            page.show_gizmo(True)

    def _control_fault(self, run: Any, exc: Exception) -> None:
        """A tick raised: pause the trial, record why, tell the experimenter; ticks stop until
        the experimenter resumes (a fault that persists pauses again at once)."""
        problem = f"{type(exc).__name__}: {exc}"[:300]
        LOGGER.error("session %s: control tick failed: %s", self.code, problem, exc_info=exc)
        self.fault = problem
        self._pause_input()
        detail = {"trial_id": getattr(run, "trial_id", None), "error": problem}
        if not self._event("control_fault", detail):
            self._unrecorded_fault = detail  # written once the store takes writes again
        try:
            if not run.paused and not run.over:
                self.session.pause()
        except Exception:
            LOGGER.exception("session %s: could not pause after a control fault", self.code)
        self._shown = None
        self._dirty.set()

    # -- the trial -----------------------------------------------------------------------------
    def _begin_run(self, run: Any, source: ParticipantInput) -> None:
        """Start ticking ``run`` (called with ``self._lock`` held)."""
        self._run, self._input = run, source
        trial = run.trial
        self.goal_names = tuple(trial.scene.object_names)
        with self._plot_lock:
            self._plot.clear()
        self._frame_key = run
        self._outcome = None
        self.fault = None
        self._input_paused = False
        self._snap(run)
        self._control = PacedLoop(
            lambda: self._tick(run), rate_hz=run.config.rate_hz, name=f"control-{self.code}"
        ).start()
        if self._render is None or not self._render.alive:
            self._render = PacedLoop(
                self._render_step, rate_hz=self.render_hz, name=f"render-{self.code}"
            ).start()
        if self.page is not None:
            self._show_trial_scene(self.page)

    def _snap(self, run: Any, record: Any = None) -> None:
        """Keep the run's body poses and the robot's intent (``record``: the tick's output)
        for the render loop when something moved, or the shown intent changed, since the last."""
        data = run.trial.sim.data
        last = self._snapshot
        intent = None if record is None else (int(record.predicted), float(record.confidence))
        if (
            last is not None
            and last[0] is run
            and float(np.max(np.abs(data.xpos - last[2]))) < MOVED_M
            and float(np.max(np.abs(data.xmat - last[3]))) < 10 * MOVED_M
            and _same_intent(last[5], intent)
        ):
            return
        seq = 0 if last is None else last[1] + 1
        self._snapshot = (run, seq, data.xpos.copy(), data.xmat.copy(), run.trial.sim.ee, intent)

    def _tick(self, run: Any) -> bool:
        if self.fault is not None:
            return not run.over  # held until the experimenter resumes
        try:
            record = run.tick()
            if record is not None:
                self._after_tick(run, record)
        except Exception as exc:  # never let the loop die silently: pause and tell
            self._control_fault(run, exc)
        return not run.over

    def _after_tick(self, run: Any, record: Any) -> None:
        """What the page and console need of a tick: the snapshot, a missed-grasp notice, the
        plots' data."""
        if TrialEvent(EventKind.GRASP_MISSED) in record.events:
            self._missed_grasp.set()  # the render loop tells the participant
        self._snap(run, record)
        with self._plot_lock:
            self._plot.append(
                (
                    float(record.t),
                    float(record.alpha),
                    float(record.confidence),
                    np.asarray(record.probabilities, float),
                )
            )

    def _show_trial_scene(self, page: ParticipantPage) -> None:
        """Scene, gizmo and keys on ``page`` for the current run (``self._lock`` held)."""
        run, source = self._run, self._input
        if run is None or source is None:
            return
        trial = run.trial
        self._ensure_view(page, trial.scene, trial.sim.model, intent=_shows_intent(run.config))
        start = source.last_target if source.last_target is not None else trial.user_target
        page.add_gizmo(np.asarray(start, float), on_target=self._on_target)
        if self._input_paused or run.paused:
            page.show_gizmo(False)

    def _preview_scene(self, page: ParticipantPage) -> None:
        """Show the next trial's scene at its start state on the ready screen, so the browser
        has loaded it (the first draw is slow in software WebGL) before the trial's clock runs."""
        from app.robot.scene import build_scene
        from app.robot.simulation import Simulation

        try:
            config = self.session.trial_config()
        except Exception:  # not on a trial step any more
            return
        scene = build_scene(config.scene)
        sim = Simulation(scene, physics_dt=config.physics_dt)
        with self._lock, self._render_lock:
            if self._run is not None and not self._run.over:
                return  # Start was pressed meanwhile: the run's own frames show
            self._frame_key = ("preview", str(scene.name))  # the render loop keeps off it
            view = self._ensure_view(page, scene, sim.model, intent=_shows_intent(config))
            view.render(sim.data.xpos, sim.data.xmat, gripper=sim.ee)

    def _ensure_view(
        self, page: ParticipantPage, scene: Any, model: Any, *, intent: bool
    ) -> SceneView:
        """The tab's view of ``scene``, with the intent ring if ``intent``: rebuilt (and the
        camera framed on the task) when the tab, the scene or the display changed
        (``self._lock`` held)."""
        key = (page.client.client_id, str(scene.name), intent)
        if self._view is None or self._view_key != key:
            page.client.scene.reset()
            self._view = SceneView(
                page.client,
                model,
                table_top=scene.spec.table.top_z,
                goals=IntentGoals.of_scene(scene) if intent else None,
            )
            self._view_key = key
            self._view_scene = scene
            self._rendered_seq = -1
            frame_scene(page.client.camera, scene)
        return self._view

    def _render_step(self) -> None:
        view, snap, page, source = self._view, self._snapshot, self.page, self._input
        if self._missed_grasp.is_set():
            self._missed_grasp.clear()
            if page is not None:
                page.notify(MISSED_GRASP)
        if view is not None and snap is not None and snap[1] != self._rendered_seq:
            with self._render_lock:
                if snap[0] is self._frame_key and view is self._view:
                    self._rendered_seq = snap[1]
                    try:
                        view.render(snap[2], snap[3], gripper=snap[4], intent=snap[5])
                    except Exception:  # a tab closing mid-frame; the next tab gets the next
                        LOGGER.debug("render failed", exc_info=True)
        if page is not None and source is not None and source.key_moved.is_set():
            source.key_moved.clear()
            if source.last_target is not None:
                page.move_gizmo(source.last_target)

    def _end_run(self) -> None:
        with self._lock:
            if self._control is not None:
                self._control.stop()
            self._control = None
            page, run = self.page, self._run
            self.fault = None  # the run it held is over (redo, skip, end)
            summary = getattr(run, "summary", None)
            if summary is not None:
                sentence = OUTCOME_SENTENCES.get(summary.outcome, "The run has ended.")
                self._outcome = sentence.format(target=getattr(run.trial.scene, "target", ""))
            elif run is not None and not self.session.finished:
                self._outcome = ENDED_BY_EXPERIMENTER  # redo or skip
            source, self._input = self._input, None  # no trial, no input: keys do nothing
        if source is not None:
            source.freeze()
        if page is not None:
            page.remove_gizmo()

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
        run = self._run
        if run is not None and run.over and self._control is not None:
            self._end_run()
        if self.closed and not self._closed_notified:
            self._closed_notified = True
            if self._render is not None:
                self._render.stop()
                self._render = None
            with contextlib.suppress(Exception):
                self.session.close()  # release the lease; the record stays readable
            if self.on_closed is not None:
                self.on_closed()
        if run is not None and not run.over:
            if (run.paused or self.fault is not None) and not self._input_paused:
                self._pause_input()
            elif not run.paused and self._input_paused and self.fault is None:
                self._resume_input()
        page = self.page
        if page is None:
            return
        screen = self.session.screen()
        key = (
            page.client.client_id,
            screen.revision,
            self._disconnect_paused,
            screen.paused,
            self.fault is not None,
            self._outcome,
        )
        if key == self._shown:
            return
        self._show(page, screen)
        self._shown = key  # only once shown: a screen that failed is tried again

    def _show(self, page: ParticipantPage, screen: Any) -> None:
        progress = screen.progress.text if screen.progress.of else None
        title, text = screen.title, screen.text
        if progress is not None and (progress in title or progress in text):
            progress = None  # said once is enough
        if self.fault is not None:
            page.show_message("Please wait", WAIT_TEXT, progress=progress)
        elif screen.paused and self._disconnect_paused:
            page.show_message(
                "Paused",
                "Your run was paused while this page was away. Press Continue when you are ready.",
                progress=progress,
                button="Continue",
                on_button=self._continue_after_disconnect,
            )
        elif screen.paused:
            page.show_message("Please wait", text or WAIT_TEXT, progress=progress)
        elif self._outcome is not None and screen.phase != "running":
            page.show_message(
                "Run finished",
                self._outcome,
                progress=progress,
                button="Continue",
                on_button=self._seen_outcome,
            )
        elif screen.phase == "consent":
            page.show_consent(
                text,
                on_agree=lambda: self._participant("agree", self.session.agree),
                agree=self._agree_label(),
                on_decline=lambda: self._participant(
                    "decline",
                    lambda: self.session.withdraw(reason="participant declined consent"),
                ),
            )
        elif screen.phase == "ready":
            self._preview_scene(page)
            page.show_message(
                title, text, progress=progress, button="Start", on_button=self._start_trial
            )
        elif screen.phase == "running":
            page.show_trial(
                heading=title,
                instruction=text,
                progress=progress,
                on_grasp=self._grasp,
                on_view=self._reframe,
            )
        elif screen.phase == "questions":
            items = [
                LikertItem(key=i.id, prompt=i.prompt, anchors=tuple(i.anchors))
                for i in screen.items
            ]
            page.show_questions(title, text, items, progress=progress, on_submit=self._answer)
        elif screen.phase == "debrief":
            page.show_message(
                title,
                text,
                progress=None,
                button="Finish",
                on_button=lambda: self._participant("finish", self.session.finish),
            )
        elif screen.phase == "done":
            page.show_message(
                title or "Done",
                (text + "\n\n" if text else "Thank you. ") + "You may close this page now.",
            )
        else:  # waiting: the protocol's welcome, and that the experimenter starts the session
            page.show_message(
                title,
                (text + "\n\n" if text else "")
                + "Please wait: the experimenter will start your session in a moment."
                " This page will change by itself.",
            )

    def _seen_outcome(self) -> None:
        self._outcome = None
        self._dirty.set()

    def _agree_label(self) -> str:
        texts = getattr(getattr(self.session, "protocol", None), "texts", None)
        return str(getattr(texts, "consent_agree", "") or "I agree")

    # -- experimenter --------------------------------------------------------------------------
    def act(self, action: str, *, reason: str = "") -> str:
        """Run an experimenter action; returns a line for the console (errors raise)."""
        s = self.session
        if action in ("redo", "skip", "withdraw", "end"):
            getattr(s, action)(reason=reason or f"{action} by the experimenter")
        elif action in ("start", "pause", "resume"):
            if action == "resume":
                self._store_takes_writes()
                if self._unrecorded_fault is not None:
                    late, self._unrecorded_fault = self._unrecorded_fault, None
                    self._event("control_fault", {**late, "recorded_late": True})
                self._disconnect_paused = False
                had_fault, self.fault = self.fault, None
                run = self._run
                if had_fault and run is not None and not run.over and not run.paused:
                    # the fault left the session unpaused (a full disk refuses the pause's
                    # own event): ticking again is the whole resume
                    self._dirty.set()
                    return f"{time.strftime('%H:%M:%S')} resume: control loop running again"
            elif action == "pause":
                self._pause_input()
            getattr(s, action)()
        else:
            raise ValueError(f"unknown action {action!r}; use one of start, pause, resume, ...")
        self._dirty.set()
        return f"{time.strftime('%H:%M:%S')} {action}: done"

    def _store_takes_writes(self, *, wait_s: float = 1.0) -> None:
        """Raise while the store still refuses this session's samples (a full or read-only
        disk); the writer retries every batch period, so give it ``wait_s`` to catch up."""
        deadline = time.monotonic() + wait_s
        while (error := getattr(self.session, "samples_error", None)) is not None:
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"the store still refuses writes ({error}); free space or fix the folder,"
                    " then resume again"
                )
            time.sleep(0.05)

    def summary(self) -> SessionSummary:
        o = self.session.overview()
        return SessionSummary(
            code=self.code,
            participant=self.participant,
            state=o.status
            + (" / paused" if o.paused else "")
            + (f" / {o.phase}" if o.phase != o.status else ""),
            position=f"{min(o.step + 1, o.steps)}/{o.steps}",
            connected=self.page is not None,
            elapsed_s=time.monotonic() - self.opened_at,
        )

    def detail(self) -> SessionDetail:
        o = self.session.overview()
        schedule = [
            (
                f"{s.kind} ({s.phase})" + (f" #{s.trial_number}" if s.trial_number else ""),
                s.task or "-",
                (s.mode or "-") + (f", {s.run} run" if s.run else ""),
            )
            for s in self.session.plan.steps
        ]
        if o.task:
            condition = (
                f"{o.training_or_task}: {o.task} ({o.difficulty}, {o.correctness}),"
                f" mode {o.mode}, {o.run} run, attempt {o.attempt}"
            )
        elif o.step_kind == "trial":
            condition = f"training, mode {o.mode}, attempt {o.attempt}"
        else:
            condition = o.step_kind or o.phase
        run = self._run
        with self._plot_lock:
            rows = list(self._plot)
        n = len(self.goal_names)
        if rows and all(len(r[3]) == n for r in rows):
            t = np.array([r[0] for r in rows])
            alpha = np.array([r[1] for r in rows])
            conf = np.array([r[2] for r in rows])
            probs = np.stack([r[3] for r in rows])
        else:
            t = alpha = conf = np.zeros(0)
            probs = np.zeros((0, n))
        return SessionDetail(
            summary=self.summary(),
            schedule=schedule,
            cursor=o.step,
            condition=condition,
            trial_elapsed_s=float(run.duration_s()) if run is not None else 0.0,
            paused=o.paused,
            t=t,
            alpha=alpha,
            confidence=conf,
            probabilities=probs,
            goal_names=self.goal_names,
            log=tuple(self.log),
            fault=self.fault or _text(getattr(self.session, "samples_error", None)),
            trials=self._trial_rows(),
        )

    def _trial_rows(self) -> tuple[tuple[str, int, str, str, str], ...]:
        """The console's list of attempts, from the store (runs of earlier processes too)."""
        try:
            records = self.session.store.trials(participant=self.participant)
        except Exception:
            LOGGER.debug("could not read the trials for the console", exc_info=True)
            return ()
        return tuple(
            (
                f"{r.trial_number}. {r.phase}" + (f": {r.task}, {r.mode}" if r.task else ""),
                int(r.attempt),
                str(r.status),
                str(r.outcome or "-"),
                "-" if r.duration_s is None else f"{r.duration_s:.1f} s",
            )
            for r in records
        )

    def close(self) -> None:
        """Stop the threads and release the session (a running trial is marked interrupted)."""
        self._stop.set()
        self._dirty.set()
        for loop in (self._control, self._render):
            if loop is not None:
                loop.stop()
        self._writer_pool.shutdown(wait=True, cancel_futures=True)
        with contextlib.suppress(Exception):
            self.session.close()


def _shows_intent(config: Any) -> bool:
    """Whether the trial of ``config`` (a ``TrialConfig``) shows the robot's intent: its mode's
    ``intent`` (``study.protocol.model.INTENT_DISPLAYS``), carried in ``config.extra``."""
    return config.extra.get("intent", "none") != "none"


def _same_intent(a: tuple[int, float] | None, b: tuple[int, float] | None) -> bool:
    """Whether intents ``a`` and ``b`` draw the same ring (same goal, same quantised opacity)."""
    if a is None or b is None:
        return a is b
    return a[0] == b[0] and ring_opacity(a[1]) == ring_opacity(b[1])


def _text(error: BaseException | None) -> str | None:
    return None if error is None else f"{type(error).__name__}: {error}"[:300]


SessionFactory = Callable[..., LiveSession]


def session_factory(store: Any, protocol: Any) -> SessionFactory:
    """Open ``participant``'s session: enrol a new ID, or reopen an unfinished one."""
    from study.session import Session

    def make(participant: str, *, code: str, title: str, render_hz: float) -> LiveSession:
        if store.has_participant(participant):
            session = Session.reopen(store, protocol, participant)
        else:
            session = Session.enrol(store, protocol, participant, seed=secrets.randbelow(2**31))
        return LiveSession(session, code=code, title=title, render_hz=render_hz)

    return make

"""``LiveRun``: the running trial of a live session, ticked by its own control loop.

A ``PacedLoop`` ticks the session's ``TrialRun`` at the protocol's control rate. Each tick hands
the bodies' poses to the view (``LiveView.snap``), a missed grasp to the render loop's notice,
and the arbitration, confidence and goal probabilities to the console's plots. A tick that
raises holds the run (``ControlFaults``), freezes the participant's input and pauses the
session, and the page is asked to redraw: the loop never dies silently. When the run is over
(``end``) the loop stops, the input is dropped and the participant's outcome sentence is set.

The live session calls ``begin``, ``show_scene`` and ``end`` with its lock held.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from app.trial import TickRecord, Trial
from app.trial.events import EventKind, TrialEvent
from study.server.inputs import ParticipantInput
from study.server.live.console import LivePlots
from study.server.live.controls import LiveInput
from study.server.live.faults import ControlFaults
from study.server.live.texts import outcome_sentence
from study.server.live.view import LiveView, shows_intent
from study.server.loop import PacedLoop
from study.server.participant import ParticipantPage
from study.session import Session, TrialRun

LOGGER = logging.getLogger("study.server.live")


class LiveRun:
    """The current (or last) run of one live session (see module docstring)."""

    def __init__(
        self,
        *,
        session: Session,
        code: str,
        view: LiveView,
        input: LiveInput,
        faults: ControlFaults,
        plots: LivePlots,
        page: Callable[[], ParticipantPage | None],
        redraw: Callable[[], None],
    ) -> None:
        self.session = session
        self.code = code
        self.view = view
        self.input = input
        self.faults = faults
        self.plots = plots
        self._page = page
        self._redraw = redraw
        self.run: TrialRun | None = None
        self.trial: Trial | None = None
        self.control: PacedLoop | None = None
        self.outcome: str | None = None
        """The sentence the participant reads after the last run, until they continue."""

    @property
    def running(self) -> bool:
        return self.run is not None and not self.run.over

    def begin(self, run: TrialRun, source: ParticipantInput) -> None:
        """Start ticking ``run`` with the participant's ``source`` driving it."""
        trial = run.trial
        if not isinstance(trial, Trial):
            raise TypeError(f"a live session runs app.trial.Trial, not {type(trial).__name__}")
        self.run, self.trial, self.input.source = run, trial, source
        self.plots.restart(trial.scene.object_names)
        self.view.follow(run)
        self.outcome = None
        self.faults.forget()
        self.view.snap(run, trial.poses())
        self.control = PacedLoop(
            lambda: self._tick(run, trial), rate_hz=run.config.rate_hz, name=f"control-{self.code}"
        ).start()
        self.view.start()
        page = self._page()
        if page is not None:
            self.show_scene(page)

    def show_scene(self, page: ParticipantPage) -> None:
        """Scene, gizmo and keys on ``page`` for the running run."""
        run, trial, source = self.run, self.trial, self.input.source
        if run is None or trial is None or source is None:
            return
        self.view.ensure(page, trial.scene, trial.sim.model, intent=shows_intent(run.config.extra))
        start = source.last_target if source.last_target is not None else trial.user_target
        page.add_gizmo(
            np.asarray(start, float),
            on_target=self.input.on_target,
            on_release=self.input.on_release,
        )
        if self.input.frozen or run.paused:
            page.show_gizmo(False)

    def gripper(self) -> np.ndarray | None:
        return None if self.trial is None else self.trial.poses().gripper

    def end(self) -> None:
        """The run is over: stop ticking, drop the input, set the outcome sentence."""
        if self.control is not None:
            self.control.stop()
        self.control = None
        self.faults.forget()  # the run it held is over (redo, skip, end)
        if self.run is not None and self.trial is not None:
            self.outcome = outcome_sentence(
                self.run, target=self.trial.scene.target, session_finished=self.session.finished
            )
        self.input.take()

    def stop(self) -> None:
        if self.control is not None:
            self.control.stop()

    # ---- control thread ------------------------------------------------------------------------
    def _tick(self, run: TrialRun, trial: Trial) -> bool:
        if self.faults.held:
            return not run.over  # held until the experimenter resumes
        try:
            record = run.tick()
            if record is not None:
                self._after_tick(run, trial, record)
        except Exception as exc:  # never let the loop die silently: pause and tell
            self._control_fault(run, exc)
        return not run.over

    def _after_tick(self, run: TrialRun, trial: Trial, record: TickRecord) -> None:
        if TrialEvent(EventKind.GRASP_MISSED) in record.events:
            self.view.missed_grasp.set()  # the render loop tells the participant
        self.view.snap(run, trial.poses(), (int(record.predicted), float(record.confidence)))
        self.plots.add(record)

    def _control_fault(self, run: TrialRun, exc: Exception) -> None:
        """Hold the run, record why, tell the experimenter; ticks stop until the experimenter
        resumes (a fault that persists pauses again at once)."""
        self.faults.hit(run, exc)
        self.input.freeze(self._page())
        try:
            if not run.paused and not run.over:
                self.session.pause()
        except Exception:
            LOGGER.exception("session %s: could not pause after a control fault", self.code)
        self._redraw()

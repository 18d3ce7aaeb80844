"""``LiveRun``: the running trial of a live session, ticked by its own control loop.

A ``PacedLoop`` ticks the session's ``TrialRun`` at the protocol's control rate. Each tick hands
the bodies' poses to the view (``LiveView.snap``), what calls for a notice (a missed grasp, the
input past the reach, the gripper resting on an object: ``LiveView.notices``) to the render
loop, and the arbitration, confidence and goal probabilities to the console's plots. A tick that
raises holds the run (``ControlFaults``), freezes the participant's input and pauses the
session, and the page is asked to redraw: the loop never dies silently. When the run is over
(``end``) the loop stops, the input is dropped and the participant's outcome sentence is set.

The live session calls ``begin``, ``show_scene`` and ``end`` with its lock held.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence

import numpy as np

from app.teleop.keyboard import KEYMAP
from app.teleop.participant_input import ParticipantInput
from app.trial import TickRecord, Trial
from app.trial.contacts import FINGERS
from app.trial.events import EventKind, TrialEvent
from study import scheduling
from study.server.live.console import LivePlots
from study.server.live.control_faults import ControlFaults
from study.server.live.controls import LiveInput
from study.server.live.notices import ResistedDescent
from study.server.live.texts import outcome_sentence
from study.server.live.view import LiveView, shows_intent
from study.server.loop import PacedLoop
from study.server.participant_page import ParticipantPage
from study.session import Session, TrialRun

LOGGER = logging.getLogger("study.server.live")

KEY_STATE_MAX_AGE_S = 1.0
"""Held keys whose state the page has not resent for this long are let go (it resends every
250 ms while a key is held): a stalled connection never leaves the arm moving."""


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
        self._resisted = ResistedDescent()

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
        self.view.notices.forget()
        self._resisted = ResistedDescent()
        self.view.snap(run, trial.poses())
        self.control = PacedLoop(
            lambda: self._tick(run, trial),
            rate_hz=run.config.rate_hz,
            name=f"control-{self.code}",
            on_start=scheduling.enter_timekeeping,
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
            on_release=lambda: self._released(page, trial),
        )
        if self.input.frozen or run.paused:
            page.show_gizmo(False)

    def _released(self, page: ParticipantPage, trial: Trial) -> None:
        """The handle was let go: with a relative mapping it returns to the gripper (and follows
        it; the reach already bounds where the gripper goes); with an absolute one, if it was
        left past the reach, it goes back over the point the arm was sent to (the reach clamps
        it), and that point becomes the input's target. (Sending that point to a relative input
        was a new displacement that also marked the handle as dragged again: it then stayed
        where it was let go instead of following the gripper.)"""
        self.input.on_release()
        source = self.input.source
        # let go during a pause: the thaw brings it inside (``LiveInput.keep_inside`` both)
        if self.trial is trial and not trial.done and source is not None and not source.frozen:
            target = source.last_target
            if target is not None:
                inside = self.input.keep_inside(target, trial.scene.reach)
                if not np.array_equal(inside, target):
                    page.move_gizmo(inside)

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
        page = self._page()
        if page is not None and (stale := page.expire_keys(KEY_STATE_MAX_AGE_S)):
            self.input.let_go(stale)
        try:
            record = run.tick()
            if record is not None:
                self._after_tick(run, trial, record)
        except Exception as exc:  # never let the loop die silently: pause and tell
            self._control_fault(run, exc)
        return not run.over

    def _after_tick(self, run: TrialRun, trial: Trial, record: TickRecord) -> None:
        notices, now = self.view.notices, time.monotonic()  # the render loop shows them
        past_reach = _held_past_reach(trial, self.input.source, record.events)
        notices.note_tick(trial, record.events, now, past_reach=past_reach)
        if self._resisted.update(
            record.t,
            z=float(record.ee[2]),
            target_z=float(trial.user_target[2]),
            touching=trial.task.reaching
            and any(part in FINGERS for part, _ in trial.contacts.touching),
        ):
            notices.resting = now
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


_PAST_REACH = (TrialEvent(EventKind.TARGET_CLAMPED), TrialEvent(EventKind.TARGET_FAR_OUTSIDE))


def _held_past_reach(
    trial: Trial, source: ParticipantInput | None, events: Sequence[TrialEvent]
) -> bool:
    """Whether the participant's input pushes past the reach this tick: the trial clamped the
    handle's target (its ``target_clamped`` events), or a held key pushes the target (which the
    keys keep inside) against a face of the reach box."""
    if any(e in events for e in _PAST_REACH):
        return True
    keyboard = getattr(source, "keyboard", None)
    if keyboard is None:
        return False
    x, reach = trial.user_target, trial.scene.reach
    for key in keyboard.held:
        axis, sign = KEYMAP.get(key, (0, 0.0))
        if (sign > 0 and x[axis] >= reach.hi[axis] - 1e-6) or (
            sign < 0 and x[axis] <= reach.lo[axis] + 1e-6
        ):
            return True
    return False

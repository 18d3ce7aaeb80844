"""What a session shows: the participant's blind ``Screen``, the experimenter's ``Overview``,
and the listeners told of every transition."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from study.session.core import SessionCore
from study.session.errors import SessionStateError
from study.session.screen import Item, Overview, Phase, Progress, Screen

if TYPE_CHECKING:
    from app.trial import TrialConfig

LOGGER = logging.getLogger("study.session")


class SessionViews(SessionCore):
    """The views of a session (every public method is thread-safe)."""

    def phase(self) -> Phase:
        with self._lock:
            return self._phase()

    def screen(self) -> Screen:
        """What the participant should see now (no condition names anywhere)."""
        with self._lock:
            phase = self._phase()
            texts = self.protocol.texts
            step = self._step()
            progress = Progress(self._trial_progress(), self.plan.n_trials)
            items: tuple[Item, ...] = ()
            actions: tuple[str, ...] = ()
            if phase == "waiting":
                title, text = "Welcome", texts.instructions["welcome"]
            elif phase == "consent":
                title, text, actions = "Consent", texts.consent, ("agree",)
            elif phase in ("ready", "running") and step is not None:
                if step.phase == "training":
                    title = f"Practice run {step.trial_number} of {self.protocol.training.runs}"
                    text = self.protocol.describe_training()
                else:
                    title = progress.text
                    text = self.protocol.describe_trial(step.task or "")
                actions = ("start_trial",) if phase == "ready" else ()
            elif phase == "questions" and step is not None:
                pending = self._pending_items(step)
                key = "preference" if step.questionnaire == "after_task" else "rating"
                title = "Questions"
                text = texts.instructions.get(key, texts.instructions["rating"])
                items = tuple(Item(i.id, i.prompt, i.scale.anchors) for i in pending)
                actions = ("answer",)
            elif phase == "debrief":
                title, text, actions = "Thank you", texts.debrief, ("finish",)
            else:
                title, text = "Done", texts.debrief if self._status == "completed" else ""
            if self._paused:
                text = texts.instructions.get("pause", "The session is paused.")
                actions = ()
            return Screen(
                phase=phase,
                title=title,
                text=text.strip(),
                progress=progress,
                items=items,
                actions=actions,
                paused=self._paused,
                questionnaire=step.questionnaire if phase == "questions" and step else None,
                revision=self._revision,
            )

    def overview(self) -> Overview:
        """The experimenter's view: the current step's full condition and the schedule."""
        with self._lock:
            step = self._step()
            run = self._active
            trials = self.store.trials(session_id=self.session_id)
            attempt = None
            if step is not None and step.kind == "trial":
                attempt = run.attempt if run else self._next_attempt(step.index)
            task = self.protocol.task(step.task) if step is not None and step.task else None
            return Overview(
                participant=self.participant,
                session_id=self.session_id,
                status=self._status,
                phase=self._phase(),
                paused=self._paused,
                step=self._cursor,
                steps=len(self.plan),
                step_kind=step.kind if step else None,
                training_or_task=step.phase if step else None,
                task=step.task if step else None,
                difficulty=task.difficulty if task else None,
                correctness=task.correctness if task else None,
                mode=step.mode if step else None,
                run=step.run if step else None,
                attempt=attempt,
                trial_id=run.trial_id if run else None,
                trials_completed=sum(t.status == "completed" for t in trials),
                ratings=len(self.store.ratings(session_id=self.session_id)),
                schedule_row=self.schedule_row,
                schedule=tuple((a.position, a.task, a.run, a.mode) for a in self._assignments),
                skipped_steps=tuple(sorted(self._skipped)),
                experimenter_actions=self._experimenter_actions(),
            )

    def trial_config(self) -> TrialConfig:
        """The current trial step's configuration (server side; carries the condition)."""
        with self._lock:
            step = self._require_phase("ready", "running", action="trial_config")
            return self._config(step)

    def _experimenter_actions(self) -> tuple[str, ...]:
        phase = self._phase()
        if phase == "done":
            return ()
        if phase == "waiting":
            return ("start", "withdraw", "end")
        actions = ["resume" if self._paused else "pause", "withdraw", "end"]
        step = self._step()
        if step is not None and step.kind in ("trial", "questions"):
            actions.append("skip")
        try:
            if self._active is not None or self._redo_target(step):
                actions.append("redo")
        except SessionStateError:
            pass
        return tuple(actions)

    def _changed(self) -> Screen:
        with self._lock:
            self._revision += 1
            listeners = list(self._listeners)
        screen = self.screen()
        for listener in listeners:
            try:
                listener(screen)
            except Exception:  # a UI's bug must not undo or block a committed transition
                LOGGER.exception("session listener %r failed", listener)
        return screen


__all__ = ["LOGGER", "SessionViews"]

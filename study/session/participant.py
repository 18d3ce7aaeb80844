"""The participant's actions on a session: ``agree``, ``start_trial``, ``answer``, ``finish``
(and the end of a trial that finished by itself)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from study.protocol import AnswerError
from study.session.core import trial_seed
from study.session.errors import InvalidAnswerError, UnknownItemError
from study.session.screen import Screen
from study.session.trial_run import TrialRun, TrialSummary
from study.session.views import SessionViews

if TYPE_CHECKING:
    from app.trial import TrialConfig


class ParticipantActions(SessionViews):
    """Participant actions (every public method is thread-safe)."""

    def agree(self) -> Screen:
        """The participant gives consent."""
        with self._lock:
            self._require_phase("consent", action="agree")
            self._advance("consent", {})
        return self._changed()

    def start_trial(self, *, input_source: Any) -> TrialRun:
        """Start the next attempt of the current trial step with ``input_source`` driving it."""
        with self._lock:
            step = self._require_phase("ready", action="start_trial")
            attempt = self._next_attempt(step.index)
            seed = trial_seed(self.seed, step.index, attempt)
            config = self._config(step)
            trial = self._factory(config, input_source, seed)
            names, positions, target = goal_info(trial, config)
            with self._tx() as tx:
                trial_id = self._insert_trial(
                    tx,
                    step,
                    attempt=attempt,
                    seed=seed,
                    goal_names=names,
                    goal_positions=positions,
                    target=target,
                )
                tx.event(
                    self.session_id,
                    self.participant,
                    "trial_start",
                    {"trial_id": trial_id, "step": step.index, "attempt": attempt, "seed": seed},
                )
            run = TrialRun(
                trial=trial,
                trial_id=trial_id,
                step=step.index,
                attempt=attempt,
                seed=seed,
                config=config,
                writer=self._writer,
                on_finished=self._trial_finished,
            )
            self._active = run
        self._changed()
        return run

    def answer(self, answers: Mapping[str, object]) -> Screen:
        """Record answers to items on the current screen (all or some of them); the session
        moves on once every item of the step is answered. Raises ``UnknownItemError`` for an
        item not pending here and ``InvalidAnswerError`` for a value off its scale; nothing is
        recorded then."""
        with self._lock:
            step = self._require_phase("questions", action="answer")
            pending = {i.id: i for i in self._pending_items(step)}
            if not answers:
                raise InvalidAnswerError(f"no answers given; pending items: {', '.join(pending)}")
            values: dict[str, int] = {}
            for item_id, value in answers.items():
                if item_id not in pending:
                    asked = {i.id for i in step.items}
                    why = "was already answered" if item_id in asked else "is not asked here"
                    raise UnknownItemError(
                        f"item {item_id!r} {why}; pending items: {', '.join(pending) or 'none'}"
                    )
                try:
                    values[item_id] = pending[item_id].check(value)
                except AnswerError as exc:
                    raise InvalidAnswerError(str(exc)) from exc
            trial_id = self._rated_trial(step)
            done = len(values) == len(pending)
            with self._tx() as tx:
                for item_id, value in values.items():
                    tx.add_rating(
                        session_id=self.session_id,
                        participant=self.participant,
                        step=step.index,
                        phase=step.phase,
                        task=step.task,
                        mode=step.mode,
                        run=step.run,
                        trial_id=trial_id,
                        item=item_id,
                        value=value,
                    )
                detail = {"step": step.index, "items": sorted(values), "trial_id": trial_id}
                tx.event(self.session_id, self.participant, "answer", detail)
                if done:
                    self._move(tx, self._next_step(step.index))
        return self._changed()

    def finish(self) -> Screen:
        """The participant has read the debrief: the session is completed."""
        with self._lock:
            self._require_phase("debrief", action="finish")
            with self._suppressed_reported() as report, self._tx() as tx:
                report(tx)
                tx.update_session(self.session_id, cursor=len(self.plan), status="completed")
                tx.event(self.session_id, self.participant, "finish", {"cursor": len(self.plan)})
            self._cursor, self._status = len(self.plan), "completed"
        return self._changed()

    def _trial_finished(self, run: TrialRun) -> None:
        """Called from the control thread when ``run``'s trial ended by itself."""
        with self._lock:
            if self._active is not run or self._closed:
                return  # aborted meanwhile by redo/skip/withdraw/end/close
            # If a commit below fails the run stays active and the next tick() retries.
            self._writer.flush()
            outcome = str(run.trial.outcome or "timeout")
            success = bool(getattr(run.trial, "success", outcome == "success"))
            summary = TrialSummary(run.trial_id, outcome, success, run.duration_s(), run.ticks)
            nxt = self._next_step(run.step)
            with self._tx() as tx:
                tx.end_trial(
                    run.trial_id,
                    status="completed",
                    outcome=outcome,
                    success=success,
                    duration_s=summary.duration_s,
                    ticks=summary.ticks,
                )
                tx.event(
                    self.session_id,
                    self.participant,
                    "trial_end",
                    {"trial_id": run.trial_id, "outcome": outcome, "cursor": nxt},
                )
                self._move(tx, nxt)
            run._finish(summary)
            self._active = None
        self._changed()


def goal_info(trial: Any, config: TrialConfig) -> tuple[list[str], list[list[float]], str]:
    """Goal names, positions (the trial's grasp points, else the objects') and the target."""
    goals = getattr(getattr(trial, "scene", None), "goals", None)
    if goals is not None:
        names = [str(n) for n in goals.names]
        positions = np.asarray(goals.positions, dtype=float).tolist()
    else:
        names = list(config.scene.object_names)
        positions = [list(map(float, o.position)) for o in config.scene.objects]
    return names, positions, config.scene.target


__all__ = ["ParticipantActions", "goal_info"]

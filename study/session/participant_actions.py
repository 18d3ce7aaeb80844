"""The participant's actions on a session: ``agree``, ``start_trial``, ``answer``, ``finish``
(and the end of a trial that finished by itself).

``ParticipantActions`` gets what it needs through its constructor: the ``Steps`` queries and
guards, the ``Ledger`` that writes, the ``RunState`` it moves, the sample writer and the trial
factory. Its methods run with the session lock held; ``Session`` takes it and tells listeners.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from app.teleop.delayed_input import delayed
from app.trial import TrialConfig
from study.protocol import Answer, AnswerError, LikertItem, NumberItem
from study.session.errors import InvalidAnswerError, UnknownItemError
from study.session.ledger import Ledger
from study.session.sample_writer import SampleWriter
from study.session.state import RunState
from study.session.steps import Steps
from study.session.trial_run import TrialFactory, TrialRun, TrialSummary


def trial_seed(session_seed: int, step: int, attempt: int) -> int:
    """A trial attempt's seed, fixed by the session seed, the step and the attempt number."""
    return int(np.random.SeedSequence([session_seed, step, attempt]).generate_state(1)[0])


class ParticipantActions:
    """Participant actions (see module docstring)."""

    def __init__(
        self,
        *,
        steps: Steps,
        ledger: Ledger,
        state: RunState,
        writer: SampleWriter,
        factory: TrialFactory,
        run_ended: Callable[[TrialRun], None],
    ) -> None:
        self.steps = steps
        self.ledger = ledger
        self.state = state
        self.writer = writer
        self.factory = factory
        self.run_ended = run_ended
        """Called from the control thread when a run's trial ended by itself; the session
        takes its lock and calls ``trial_finished``."""

    def agree(self) -> None:
        self.steps.require_phase("consent", action="agree")
        nxt = self.steps.next_step(self.state.cursor)
        with self.ledger.tx() as tx:
            self.ledger.event(tx, "consent", {"cursor": nxt})
            self.ledger.move(tx, nxt)

    def start_trial(self, input_source: Any) -> TrialRun:
        step = self.steps.require_phase("ready", action="start_trial")
        attempt = self.steps.next_attempt(step.index)
        seed = trial_seed(self.ledger.info.seed, step.index, attempt)
        config = self.steps.config(step)
        latency_s = float(config.extra.get("latency_s", 0.0))  # a level's added latency
        source = delayed(input_source, latency_s=latency_s, rate_hz=config.rate_hz)
        trial = self.factory(config, source, seed)
        names, positions, target = goal_info(trial, config)
        with self.ledger.tx() as tx:
            trial_id = self.ledger.insert_trial(
                tx,
                step,
                attempt=attempt,
                seed=seed,
                goal_names=names,
                goal_positions=positions,
                target=target,
            )
            self.ledger.event(
                tx,
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
            writer=self.writer,
            on_finished=self.run_ended,
            is_paused=lambda: self.state.paused,
        )
        self.state.active = run
        return run

    def answer(self, answers: Mapping[str, object]) -> None:
        """Record answers to pending items (all or some); ``UnknownItemError`` for an item not
        pending here, ``InvalidAnswerError`` for a value the item refuses (nothing recorded).
        Likert answers go to ``ratings``, every other kind to ``answers``."""
        step = self.steps.require_phase("questions", action="answer")
        pending = {i.id: i for i in self.steps.pending_items(step)}
        if not answers:
            raise InvalidAnswerError(f"no answers given; pending items: {', '.join(pending)}")
        values: dict[str, Answer] = {}
        for item_id, value in answers.items():
            if item_id not in pending:
                asked = {i.id for i in step.items}
                why = "was already answered" if item_id in asked else "is not asked here"
                raise UnknownItemError(
                    f"item {str(item_id)[:40]!r} {why}; pending items:"
                    f" {', '.join(pending) or 'none'}"
                )
            try:
                values[item_id] = pending[item_id].check(value)
            except AnswerError as exc:
                raise InvalidAnswerError(str(exc)) from exc
        trial_id = self.steps.rated_trial(step)
        info = self.ledger.info
        with self.ledger.tx() as tx:
            for item_id, value in values.items():
                item = pending[item_id]
                if isinstance(item, LikertItem):
                    tx.add_rating(
                        session_id=info.session_id,
                        participant=info.participant,
                        step=step.index,
                        phase=step.phase,
                        task=step.task,
                        mode=step.mode,
                        run=step.run,
                        trial_id=trial_id,
                        item=item_id,
                        value=int(value),  # type: ignore[arg-type]
                    )
                else:
                    tx.add_answer(
                        session_id=info.session_id,
                        participant=info.participant,
                        step=step.index,
                        questionnaire=step.questionnaire or "",
                        item=item_id,
                        kind=item.kind,
                        value=_as_text(value),
                        number=float(value)
                        if isinstance(item, NumberItem) and value is not None
                        else None,
                    )
            detail = {"step": step.index, "items": sorted(values), "trial_id": trial_id}
            self.ledger.event(tx, "answer", detail)
            if len(values) == len(pending):
                self.ledger.move(tx, self.steps.next_step(step.index))

    def finish(self) -> None:
        self.steps.require_phase("debrief", action="finish")
        end = len(self.steps.plan)
        with self.ledger.suppressed_reported() as report, self.ledger.tx() as tx:
            report(tx)
            tx.update_session(self.ledger.info.session_id, cursor=end, status="completed")
            self.ledger.event(tx, "finish", {"cursor": end})
        self.state.cursor, self.state.status = end, "completed"

    def trial_finished(self, run: TrialRun) -> bool:
        """Commit ``run``, whose trial ended by itself, and move on; False if it was aborted
        meanwhile (redo, skip, withdraw, end, close). If a commit fails the run stays active
        and its next tick retries."""
        if self.state.active is not run or self.state.closed:
            return False
        self.writer.flush()
        outcome = str(run.trial.outcome or "timeout")
        success = bool(getattr(run.trial, "success", outcome == "success"))
        summary = TrialSummary(run.trial_id, outcome, success, run.duration_s(), run.ticks)
        nxt = self.steps.next_step(run.step)
        with self.ledger.tx() as tx:
            tx.end_trial(
                run.trial_id,
                status="completed",
                outcome=outcome,
                success=success,
                duration_s=summary.duration_s,
                ticks=summary.ticks,
            )
            self.ledger.event(
                tx, "trial_end", {"trial_id": run.trial_id, "outcome": outcome, "cursor": nxt}
            )
            self.ledger.move(tx, nxt)
        run.end(summary)
        self.state.active = None
        return True


def _as_text(value: Answer) -> str | None:
    """An answer as stored in ``answers.value``: text as given, a number without a spurious
    ``.0`` (``7.5``, ``12``)."""
    if value is None or isinstance(value, str):
        return value
    return str(int(value)) if float(value).is_integer() else repr(float(value))


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


__all__ = ["ParticipantActions", "goal_info", "trial_seed"]

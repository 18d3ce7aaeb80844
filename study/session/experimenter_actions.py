"""The experimenter's actions on a session: ``start``, ``pause``, ``resume``, ``redo``,
``skip``, ``withdraw``, ``end`` (the last four need a reason for the record: ``NEEDS_REASON``).

``ExperimenterActions`` gets the ``Steps`` queries and guards, the ``Ledger`` that writes, the
``RunState`` it changes and the ``SampleWriter`` whose rows it commits before a run is aborted.
Its methods run with the session lock held; ``Session`` takes it and tells listeners.
"""

from __future__ import annotations

from study.session.errors import MissingReasonError, SessionStateError
from study.session.ledger import Ledger
from study.session.plan import Step
from study.session.sample_writer import SampleWriter
from study.session.state import PauseCause, RunState
from study.session.steps import Steps
from study.session.trial_run import TrialRun
from study.store import Transaction


class ExperimenterActions:
    """Experimenter actions (see module docstring)."""

    def __init__(
        self, *, steps: Steps, ledger: Ledger, state: RunState, writer: SampleWriter
    ) -> None:
        self.steps = steps
        self.ledger = ledger
        self.state = state
        self.writer = writer

    def start(self) -> None:
        self.steps.require_phase("waiting", action="start")
        with self.ledger.tx() as tx:
            tx.update_session(self.ledger.info.session_id, status="running")
            self.ledger.event(tx, "start", {"cursor": self.state.cursor})
        self.state.status, self.state.started = "running", True

    def pause(self, cause: PauseCause) -> None:
        self.steps.require_live("pause")
        if self.state.paused:
            raise SessionStateError("the session is already paused; resume() continues it")
        with self.ledger.tx() as tx:
            self.ledger.event(tx, "pause", {**self.ledger.where(), "cause": cause})
        self.state.set_paused(cause)

    def resume(self) -> None:
        self.steps.require_live("resume")
        if not self.state.paused:
            raise SessionStateError("the session is not paused; nothing to resume")
        with self.ledger.tx() as tx:
            self.ledger.event(tx, "resume", self.ledger.where())
        self.state.set_paused(None)

    def redo(self, reason: str) -> None:
        reason = check_reason(reason, "redo")
        self.steps.require_live("redo")
        run = self.state.active
        if run is None:
            target, trial_id = self.steps.redo_target()
        self.stop(run)
        with self.ledger.tx() as tx:
            if run is not None:
                self.ledger.record_abort(tx, run, status="redone", note=f"redone: {reason}")
                target, trial_id = run.step, run.trial_id
            else:
                tx.set_trial_status(trial_id, "redone", note=f"redone: {reason}")
                tx.update_session(self.ledger.info.session_id, cursor=target)
            detail = {"step": target, "trial_id": trial_id, "reason": reason, "cursor": target}
            self.ledger.event(tx, "redo", detail)
        self.state.cursor = target

    def skip(self, reason: str) -> None:
        reason = check_reason(reason, "skip")
        self.steps.require_live("skip")
        step = self.steps.current()
        if step is None or step.kind not in ("trial", "questions"):
            raise SessionStateError(
                f"skip applies to trials and questions, not to the {self.steps.phase()} screen"
            )
        skipped = [step.index]
        run = self.state.active
        self.stop(run)
        with self.ledger.tx() as tx:
            trial_id = None
            if step.kind == "trial":
                plan = self.steps.plan
                lost = plan.dependents(step.index, skipped=self.state.skipped)
                skipped += [s for s in lost if s not in skipped]
                if run is not None:
                    trial_id = run.trial_id
                    self.ledger.record_abort(tx, run, status="skipped", note=f"skipped: {reason}")
                else:
                    trial_id = self._skipped_trial_row(tx, step, reason)
            self.state.skipped.update(skipped)
            nxt = self.steps.next_step(step.index)
            detail = {"steps": skipped, "trial_id": trial_id, "reason": reason, "cursor": nxt}
            self.ledger.event(tx, "skip", detail)
            self.ledger.move(tx, nxt)

    def terminate(self, status: str, reason: str) -> None:
        """``withdrawn`` (the participant withdrew) or ``ended`` (by the experimenter)."""
        action = "withdraw" if status == "withdrawn" else "end"
        reason = check_reason(reason, action)
        self.ledger.require_open()
        if self.state.finished:
            raise SessionStateError(f"the session is already {self.state.status}")
        run = self.state.active
        self.stop(run)
        with self.ledger.suppressed_reported() as report, self.ledger.tx() as tx:
            if run is not None:
                note = f"{status}: {reason}"
                self.ledger.record_abort(tx, run, status="interrupted", note=note)
            report(tx)
            tx.update_session(self.ledger.info.session_id, status=status)
            self.ledger.event(tx, action, {"reason": reason, "cursor": self.state.cursor})
        self.state.status, self.state.paused_by = status, None

    def stop(self, run: TrialRun | None) -> None:
        """Stop ``run`` (no further ticks) and commit its samples; call before the transaction
        that records how it ended (``Ledger.record_abort``)."""
        if run is not None:
            run.end(None)
            self.writer.flush()

    def _skipped_trial_row(self, tx: Transaction, step: Step, reason: str) -> int:
        config = self.steps.config(step)
        trial_id = self.ledger.insert_trial(
            tx,
            step,
            attempt=self.steps.next_attempt(step.index),
            seed=0,
            goal_names=list(config.scene.object_names),
            goal_positions=[list(o.position) for o in config.scene.objects],
            target=config.scene.target,
            status="skipped",
            note=f"skipped: {reason}",
        )
        tx.end_trial(
            trial_id, status="skipped", outcome=None, success=None, duration_s=None, ticks=0
        )
        return trial_id


def check_reason(reason: str, action: str) -> str:
    """``reason`` stripped, else ``MissingReasonError`` (redo, skip, withdraw, end need one)."""
    if not isinstance(reason, str) or not reason.strip():
        raise MissingReasonError(f"{action} needs a reason for the record (e.g. reason='...')")
    return reason.strip()


__all__ = ["ExperimenterActions", "check_reason"]

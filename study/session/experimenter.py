"""The experimenter's actions on a session: ``start``, ``pause``, ``resume``, ``redo``,
``skip``, ``withdraw``, ``end`` (the last four need a reason for the record)."""

from __future__ import annotations

from study.session.core import FINAL_STATUSES
from study.session.errors import MissingReasonError, SessionStateError
from study.session.plan import Step
from study.session.screen import Screen
from study.session.views import SessionViews
from study.store import Transaction


class ExperimenterActions(SessionViews):
    """Experimenter actions (every public method is thread-safe)."""

    def start(self) -> Screen:
        """Start the session (or continue it in this process after a restart)."""
        with self._lock:
            self._require_phase("waiting", action="start")
            with self._tx() as tx:
                tx.update_session(self.session_id, status="running")
                tx.event(self.session_id, self.participant, "start", {"cursor": self._cursor})
            self._status, self._started = "running", True
        return self._changed()

    def pause(self) -> Screen:
        """Pause the session (and the running trial; paused time is not trial time)."""
        with self._lock:
            self._require_live("pause")
            if self._paused:
                raise SessionStateError("the session is already paused; resume() continues it")
            with self._tx() as tx:
                tx.event(self.session_id, self.participant, "pause", self._where())
            if self._active:
                self._active._pause()
            self._paused = True
        return self._changed()

    def resume(self) -> Screen:
        """Continue a paused session."""
        with self._lock:
            self._require_live("resume")
            if not self._paused:
                raise SessionStateError("the session is not paused; nothing to resume")
            with self._tx() as tx:
                tx.event(self.session_id, self.participant, "resume", self._where())
            if self._active:
                self._active._resume()
            self._paused = False
        return self._changed()

    def redo(self, *, reason: str) -> Screen:
        """Run a trial again: the running attempt, or the one just completed if nothing after it
        has started or been answered. The earlier attempt is kept, marked ``redone``."""
        reason = _reason(reason, "redo")
        with self._lock:
            self._require_live("redo")
            run, step = self._active, self._step()
            if run is None:
                target, trial_id = self._redo_target(step)
            self._stop(run)
            with self._tx() as tx:
                if run is not None:
                    self._record_abort(tx, run, status="redone", note=f"redone: {reason}")
                    target, trial_id = run.step, run.trial_id
                else:
                    tx.set_trial_status(trial_id, "redone", note=f"redone: {reason}")
                    tx.update_session(self.session_id, cursor=target)
                tx.event(
                    self.session_id,
                    self.participant,
                    "redo",
                    {"step": target, "trial_id": trial_id, "reason": reason, "cursor": target},
                )
            self._cursor = target
        return self._changed()

    def skip(self, *, reason: str) -> Screen:
        """Skip the current trial (with its follow-up items) or the current items."""
        reason = _reason(reason, "skip")
        with self._lock:
            self._require_live("skip")
            step = self._step()
            if step is None or step.kind not in ("trial", "questions"):
                raise SessionStateError(
                    f"skip applies to trials and questions, not to the {self._phase()} screen"
                )
            skipped = [step.index]
            self._stop(self._active)
            with self._tx() as tx:
                trial_id = None
                if step.kind == "trial":
                    skipped += [s for s in self.plan.dependents(step.index) if s not in skipped]
                    if self._active is not None:
                        trial_id = self._active.trial_id
                        self._record_abort(
                            tx, self._active, status="skipped", note=f"skipped: {reason}"
                        )
                    else:
                        trial_id = self._skipped_trial_row(tx, step, reason)
                self._skipped.update(skipped)
                nxt = self._next_step(step.index)
                tx.event(
                    self.session_id,
                    self.participant,
                    "skip",
                    {"steps": skipped, "trial_id": trial_id, "reason": reason, "cursor": nxt},
                )
                self._move(tx, nxt)
        return self._changed()

    def withdraw(self, *, reason: str = "participant withdrew") -> Screen:
        """The participant withdraws: the session ends, everything recorded is kept."""
        return self._terminate("withdrawn", _reason(reason, "withdraw"))

    def end(self, *, reason: str) -> Screen:
        """The experimenter ends the session early (recorded data kept)."""
        return self._terminate("ended", _reason(reason, "end"))

    def _skipped_trial_row(self, tx: Transaction, step: Step, reason: str) -> int:
        config = self._config(step)
        trial_id = self._insert_trial(
            tx,
            step,
            attempt=self._next_attempt(step.index),
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

    def _terminate(self, status: str, reason: str) -> Screen:
        with self._lock:
            self._require_open()
            if self._status in FINAL_STATUSES:
                raise SessionStateError(f"the session is already {self._status}")
            self._stop(self._active)
            with self._suppressed_reported() as report, self._tx() as tx:
                if self._active is not None:
                    self._record_abort(
                        tx, self._active, status="interrupted", note=f"{status}: {reason}"
                    )
                report(tx)
                tx.update_session(self.session_id, status=status)
                tx.event(
                    self.session_id,
                    self.participant,
                    "withdraw" if status == "withdrawn" else "end",
                    {"reason": reason, "cursor": self._cursor},
                )
            self._status, self._paused = status, False
        return self._changed()


def _reason(reason: str, action: str) -> str:
    if not isinstance(reason, str) or not reason.strip():
        raise MissingReasonError(f"{action} needs a reason for the record (e.g. reason='...')")
    return reason.strip()


__all__ = ["ExperimenterActions"]

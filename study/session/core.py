"""The session core: a participant's session state bound to this process, and the internal steps
every transition is made of (phase, cursor moves, lease-checked transactions, trial rows).

The participant- and experimenter-facing parts build on ``SessionCore``
(``study.session.views``, ``study.session.participant``, ``study.session.experimenter``,
``study.session.opening``); ``study.session.Session`` puts them together. Methods whose names start
with ``_`` are called with ``self._lock`` held.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Self

import numpy as np

from study.session.errors import SessionClosedError, SessionError, SessionStateError
from study.session.event_limit import EventLimiter
from study.session.lease_keeper import LeaseKeeper
from study.session.plan import Plan, Step, build_plan
from study.session.sample_writer import SampleWriter
from study.session.screen import Phase, Screen
from study.session.store_open import check_protocol
from study.session.trial_run import TrialFactory, TrialRun
from study.store import SessionLockedError, Store, StoreError, Transaction

if TYPE_CHECKING:
    from app.trial import TrialConfig
    from study.protocol import Protocol

_LOG = logging.getLogger("study.session")
FINAL_STATUSES = ("completed", "withdrawn", "ended")
Listener = Callable[[Screen], None]
PARTICIPANT_ACTIONS: dict[str, tuple[str, ...]] = {
    "consent": ("agree",),
    "ready": ("start_trial",),
    "questions": ("answer",),
    "debrief": ("finish",),
}


def default_trial_factory(config: TrialConfig, input_source: Any, seed: int) -> Any:
    """``app.trial.Trial(config, input_source, seed=seed)`` (imported on first use)."""
    from app.trial import Trial  # type: ignore[attr-defined]

    return Trial(config, input_source, seed=seed)


def trial_seed(session_seed: int, step: int, attempt: int) -> int:
    """A trial attempt's seed, fixed by the session seed, the step and the attempt number."""
    return int(np.random.SeedSequence([session_seed, step, attempt]).generate_state(1)[0])


class SessionCore:
    """A participant's session state bound to this process (holds the session's lease)."""

    def __init__(
        self,
        *,
        store: Store,
        protocol: Protocol,
        participant: str,
        trial_factory: TrialFactory | None,
        heartbeat_s: float,
        flush_interval_s: float,
    ) -> None:
        check_protocol(store, protocol)
        self.store = store
        self.protocol = protocol
        self.participant = participant
        self._factory = trial_factory or default_trial_factory
        self._lock = threading.RLock()
        self._listeners: list[Listener] = []
        record = store.session(participant)
        self.session_id = record.session_id
        self.seed = record.seed
        self._status = record.status
        self._cursor = record.cursor
        self.schedule_row = store.participant(participant).schedule_row
        self._assignments = store.assignments(participant)
        self.plan: Plan = build_plan(protocol, self._assignments)
        self._skipped: set[int] = set()
        for event in store.events(session_id=self.session_id):
            if event.kind == "skip":
                self._skipped.update(event.detail.get("steps", []))
        self._lease = store.acquire_lease(participant)
        self._keeper = LeaseKeeper(store, self._lease, interval_s=heartbeat_s)
        self._writer = SampleWriter(store, flush_interval_s=flush_interval_s)
        self._events = EventLimiter()
        self._started = False
        self._paused = False
        self._closed = False
        self._active: TrialRun | None = None
        self._revision = 0

    # ---- state ----------------------------------------------------------------------------------
    @property
    def status(self) -> str:
        """``enrolled``, ``running``, ``completed``, ``withdrawn`` or ``ended``."""
        return self._status

    @property
    def cursor(self) -> int:
        return self._cursor

    @property
    def active_run(self) -> TrialRun | None:
        """The running trial attempt, if any (for the control loop to tick)."""
        return self._active

    @property
    def samples_error(self) -> BaseException | None:
        """Why this session's samples are not reaching the store (a full or read-only disk:
        ``StoreWriteError``), or ``None``. The rows are held in memory and retried every batch
        period, so this turns ``None`` again by itself once the disk takes writes; a live
        server can show it to the experimenter and hold the trial until then."""
        return self._writer.error

    @property
    def finished(self) -> bool:
        return self._status in FINAL_STATUSES

    def record_event(self, kind: str, detail: Mapping[str, Any] | None = None) -> None:
        """Append an event of the caller's to the session's log: the one way for a UI, server or
        simulator to log its own events (tab connected, input rejected, simulated parameters).

            session.record_event("participant_connected", {"client": 3})

        ``detail`` must be JSON-serialisable. Thread-safe. Each kind is rate-limited (10 at
        once, then 1 per second; ``study.session.event_limit``) because a client can trigger some at
        will: an event over the limit is counted instead of written, and the next one written
        carries ``"suppressed": k``; counts still pending at ``close()`` are written there as
        one ``events_suppressed`` event. The event is written in the same
        transaction that checks this process still holds the participant's lease, so a session
        taken over by another process (``SessionLockedError``) or closed
        (``SessionClosedError``) cannot add to the log; nothing is written then. Prefer this to
        ``store.transaction()`` + ``tx.event(...)``, which skips that check."""
        if not isinstance(kind, str) or not kind:
            raise SessionError("an event needs a kind (a short name such as 'tab_connected')")
        detail = dict(detail or {})
        try:
            json.dumps(detail)
        except (TypeError, ValueError) as exc:
            raise SessionError(
                f"event {kind!r}: detail must be JSON-serialisable (str, numbers, lists, dicts): "
                f"{exc}; convert arrays with .tolist()"
            ) from None
        with self._lock:
            self._require_open()
            suppressed = self._events.admit(kind)
            if suppressed is None:
                return  # over this kind's rate: counted, reported with the next one written
            if suppressed:
                detail["suppressed"] = suppressed
            try:
                with self._tx() as tx:
                    tx.event(self.session_id, self.participant, kind, detail)
            except BaseException:
                self._events.restore(kind, suppressed)
                raise

    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(screen)`` after every transition (from the acting thread)."""
        with self._lock:
            self._listeners.append(listener)

    # ---- release --------------------------------------------------------------------------------
    def close(self) -> None:
        """Release this process's hold on the session (a running trial is marked interrupted).
        The session can be continued later with ``Session.reopen``. Idempotent.

        If the store refuses writes (full disk, read-only: ``StoreWriteError``) the session is
        still closed -- the writer and heartbeat threads stop, nothing more is written -- and the
        first such error is raised afterwards. The file then stays consistent: a running trial
        whose samples could not be committed stays ``running`` on file, which readers report as
        interrupted (its ``ticks`` being the samples that did reach the file) and
        ``Session.reopen`` records as such, so ``--resume`` continues once the disk is fixed."""
        errors: list[StoreError] = []
        with self._lock:
            if self._closed:
                return
            try:
                if not self._keeper.lost and self._status not in FINAL_STATUSES:
                    self._close_in_store(errors)
            finally:
                self._closed = True
                try:
                    self._writer.close()
                except StoreError as exc:
                    errors.append(exc)
                try:
                    self._keeper.stop(release=True)
                except StoreError as exc:
                    errors.append(exc)
        if errors:
            raise errors[0]

    def _close_in_store(self, errors: list[StoreError]) -> None:
        where, run = self._where(), self._active
        try:
            self._stop(run)
        except StoreError as exc:
            # The run's last samples are not on file: recording it with run.ticks would claim
            # samples the file does not have, so it is left to the orphan rule (see close).
            errors.append(exc)
            return
        try:
            with self._suppressed_reported() as report, self._tx() as tx:
                if run is not None:
                    self._record_abort(tx, run, status="interrupted", note="session closed")
                report(tx)
                tx.event(self.session_id, self.participant, "close", where)
        except SessionLockedError:
            # Another process took the session over before the keeper noticed: the data are
            # now theirs to write, and there is nothing to release.
            _LOG.warning("session %s was taken over; closed without writing", self.participant)
        except StoreError as exc:
            errors.append(exc)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- internals (called with self._lock held) ---------------------------------------------------
    def _phase(self) -> Phase:
        if self._status in FINAL_STATUSES:
            return "done"
        if not self._started:
            return "waiting"
        step = self._step()
        if step is None:
            return "done"
        if step.kind == "trial":
            return "running" if self._active is not None else "ready"
        return step.kind  # consent, questions, debrief

    def _step(self) -> Step | None:
        return self.plan[self._cursor] if self._cursor < len(self.plan) else None

    def _require_open(self) -> None:
        if self._closed:
            raise SessionClosedError(
                f"this session object for {self.participant} is closed; reopen the session"
            )
        if self._keeper.lost:
            raise SessionClosedError(
                f"participant {self.participant}'s session was taken over by another process"
            )

    def _require_live(self, action: str) -> None:
        self._require_open()
        phase = self._phase()
        if phase in ("waiting", "done"):
            raise SessionStateError(
                f"cannot {action}: the session is {self._status if phase == 'done' else phase}"
                f"{'' if phase == 'done' else ' (call start() first)'}"
            )

    def _require_phase(self, *phases: Phase, action: str) -> Step:
        self._require_open()
        phase = self._phase()
        if phase not in phases:
            valid = ", ".join(self._participant_actions(phase)) or "none"
            raise SessionStateError(
                f"cannot {action} on the {phase} screen (status {self._status}); "
                f"participant actions valid now: {valid}"
            )
        if self._paused and action != "trial_config":
            raise SessionStateError(f"cannot {action}: the session is paused (resume() first)")
        step = self._step()
        assert step is not None or phase == "waiting"
        return step  # type: ignore[return-value]

    def _participant_actions(self, phase: Phase) -> tuple[str, ...]:
        return PARTICIPANT_ACTIONS.get(phase, ())

    @contextmanager
    def _tx(self) -> Iterator[Transaction]:
        """A store transaction that first checks this process still holds the lease; if it
        fails, the in-memory cursor and skipped steps are restored with the rolled-back file."""
        cursor, skipped = self._cursor, set(self._skipped)
        try:
            with self.store.transaction() as tx:
                tx.require_lease(self._lease)
                yield tx
        except BaseException:
            self._cursor, self._skipped = cursor, skipped
            raise

    def _where(self) -> dict[str, Any]:
        run = self._active
        return {"cursor": self._cursor, "trial_id": run.trial_id if run else None}

    def _advance(self, kind: str, detail: dict[str, Any]) -> None:
        nxt = self._next_step(self._cursor)
        with self._tx() as tx:
            tx.event(self.session_id, self.participant, kind, {**detail, "cursor": nxt})
            self._move(tx, nxt)

    def _move(self, tx: Transaction, cursor: int) -> None:
        tx.update_session(self.session_id, cursor=cursor)
        self._cursor = cursor

    def _next_step(self, index: int) -> int:
        nxt = index + 1
        while nxt < len(self.plan) - 1 and nxt in self._skipped:
            nxt += 1
        return nxt

    def _trial_progress(self) -> int:
        """The trial number shown: the current trial step's, else the last one passed."""
        done = [s.trial_number for s in self.plan.steps[: self._cursor + 1] if s.trial_number]
        return max(done, default=0)

    def _next_attempt(self, step: int) -> int:
        trials = self.store.trials(session_id=self.session_id)
        attempts = [t.attempt for t in trials if t.step == step]
        return max(attempts, default=0) + 1

    def _config(self, step: Step) -> TrialConfig:
        if step.phase == "training":
            return self.protocol.training_config()
        return self.protocol.trial_config(step.task or "", step.mode or "")

    def _pending_items(self, step: Step) -> list[Any]:
        answered = {
            r.item for r in self.store.ratings(session_id=self.session_id) if r.step == step.index
        }
        return [i for i in step.items if i.id not in answered]

    def _rated_trial(self, step: Step) -> int | None:
        """The completed trial attempt an after-run item is about (``None`` for other items)."""
        if step.rates_step is None:
            return None
        completed = [
            t.trial_id
            for t in self.store.trials(session_id=self.session_id)
            if t.step == step.rates_step and t.status == "completed"
        ]
        return completed[-1] if completed else None

    def _redo_target(self, step: Step | None) -> tuple[int, int]:
        """The completed trial just before the cursor that ``redo`` may run again."""
        prev = self._cursor - 1
        if prev < 0 or self.plan[prev].kind != "trial" or prev in self._skipped:
            raise SessionStateError(
                "nothing to redo: no trial is running and the previous step is not a completed "
                "trial"
            )
        trials = self.store.trials(session_id=self.session_id)
        if any(t.step == self._cursor for t in trials) or (
            step is not None
            and step.kind == "questions"
            and self._pending_items(step) != list(step.items)
        ):
            raise SessionStateError(
                "cannot redo the previous trial: the step after it has already started or been "
                "answered"
            )
        done = [t.trial_id for t in trials if t.step == prev and t.status == "completed"]
        if not done:
            raise SessionStateError("nothing to redo: the previous trial has no completed attempt")
        return prev, done[-1]

    def _insert_trial(
        self,
        tx: Transaction,
        step: Step,
        *,
        attempt: int,
        seed: int,
        goal_names: list[str],
        goal_positions: list[list[float]],
        target: str,
        **extra: Any,
    ) -> int:
        """Insert an attempt of the trial ``step`` with its condition (task, difficulty,
        correctness, mode, run) from the plan and the protocol; ``extra`` columns as given."""
        task = self.protocol.task(step.task) if step.task else None
        return tx.insert_trial(
            session_id=self.session_id,
            participant=self.participant,
            step=step.index,
            trial_number=step.trial_number,
            phase=step.phase,
            position=step.position,
            task=step.task,
            difficulty=task.difficulty if task else None,
            correctness=task.correctness if task else None,
            mode=step.mode,
            run=step.run,
            attempt=attempt,
            seed=seed,
            goal_names=goal_names,
            goal_positions=goal_positions,
            target=target,
            **extra,
        )

    @contextmanager
    def _suppressed_reported(self) -> Iterator[Callable[[Transaction], None]]:
        """``with self._suppressed_reported() as report: ... report(tx)`` writes the counts of
        rate-limited events not yet reported (see ``record_event``) in ``tx``; they are cleared
        only if the ``with`` block (holding the transaction) completes."""
        pending = self._events.pending()

        def report(tx: Transaction) -> None:
            if pending:
                tx.event(
                    self.session_id, self.participant, "events_suppressed", {"counts": pending}
                )

        yield report
        self._events.reported(pending)

    def _stop(self, run: TrialRun | None) -> None:
        """Stop ``run`` (no further ticks) and commit its samples; call before the transaction
        that records how it ended (``_record_abort``)."""
        if run is not None:
            run._finish(None)
            self._writer.flush()

    def _record_abort(self, tx: Transaction, run: TrialRun, *, status: str, note: str) -> None:
        """Record the stopped ``run`` with ``status`` (outcome ``aborted``)."""
        tx.end_trial(
            run.trial_id,
            status=status,
            outcome="aborted",
            success=False,
            duration_s=run.duration_s(),
            ticks=run.ticks,
            note=note,
        )
        self._active = None


__all__ = ["FINAL_STATUSES", "Listener", "SessionCore", "default_trial_factory", "trial_seed"]

"""``Ledger``: a session's writes to the store, each checked against this process's lease.

Every transition of the engine is one ``with ledger.tx() as tx:`` block: the transaction first
checks the lease (so a process that lost the session to another writes nothing) and, if the block
fails, puts the ``RunState``'s cursor and skipped steps back with the rolled-back file. The rows
the transitions share (a trial attempt with its condition, the record of an aborted run, the
counts of rate-limited events) are written here too.

Called with the session lock held (``study.session`` explains the locks).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from study.protocol import Protocol
from study.session.errors import SessionClosedError, SessionError
from study.session.event_limit import EventLimiter
from study.session.lease_keeper import LeaseKeeper
from study.session.plan import Step
from study.session.state import RunState
from study.session.trial_run import TrialRun
from study.store import AssignmentRecord, Lease, Store, Transaction


@dataclass(frozen=True)
class SessionInfo:
    """Who and what a session is: fixed for its lifetime."""

    participant: str
    session_id: int
    seed: int
    schedule_row: int
    assignments: tuple[AssignmentRecord, ...]
    by_link: bool = False
    """Enrolled by the open link (its ``enrol`` event holds recruitment IDs): an online
    participant, with no experimenter beside them (``Texts.for_link``)."""


class Ledger:
    """Lease-checked transactions for one session (see module docstring)."""

    def __init__(
        self,
        *,
        store: Store,
        protocol: Protocol,
        info: SessionInfo,
        state: RunState,
        lease: Lease,
        keeper: LeaseKeeper,
    ) -> None:
        self.store = store
        self.protocol = protocol
        self.info = info
        self.state = state
        self.lease = lease
        self.keeper = keeper
        self.limiter = EventLimiter()

    def require_open(self) -> None:
        """Raise ``SessionClosedError`` if this object was closed or the lease was taken over."""
        who = self.info.participant
        if self.state.closed:
            raise SessionClosedError(f"this session object for {who} is closed; reopen the session")
        if self.keeper.lost:
            raise SessionClosedError(
                f"participant {who}'s session was taken over by another process"
            )

    @contextmanager
    def tx(self) -> Iterator[Transaction]:
        """A store transaction that first checks this process still holds the lease; if it
        fails, the state's cursor and skipped steps are restored with the rolled-back file."""
        saved = self.state.saved()
        try:
            with self.store.transaction() as tx:
                tx.require_lease(self.lease)
                yield tx
        except BaseException:
            self.state.restore(saved)
            raise

    def event(self, tx: Transaction, kind: str, detail: Mapping[str, Any]) -> None:
        tx.event(self.info.session_id, self.info.participant, kind, dict(detail))

    def move(self, tx: Transaction, cursor: int) -> None:
        """Move the session (file and state) to step ``cursor``."""
        tx.update_session(self.info.session_id, cursor=cursor)
        self.state.cursor = cursor

    def where(self) -> dict[str, Any]:
        run = self.state.active
        return {"cursor": self.state.cursor, "trial_id": run.trial_id if run else None}

    def record_event(self, kind: str, detail: Mapping[str, Any] | None) -> None:
        """A caller's own event, rate-limited per kind (``Session.record_event`` documents it)."""
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
        self.require_open()
        suppressed = self.limiter.admit(kind)
        if suppressed is None:
            return  # over this kind's rate: counted, reported with the next one written
        if suppressed:
            detail["suppressed"] = suppressed
        try:
            with self.tx() as tx:
                self.event(tx, kind, detail)
        except BaseException:
            self.limiter.restore(kind, suppressed)
            raise

    @contextmanager
    def suppressed_reported(self) -> Iterator[Callable[[Transaction], None]]:
        """``with ledger.suppressed_reported() as report: ... report(tx)`` writes the counts of
        rate-limited events not yet reported in ``tx``; they are cleared only if the ``with``
        block (holding the transaction) completes."""
        pending = self.limiter.pending()

        def report(tx: Transaction) -> None:
            if pending:
                self.event(tx, "events_suppressed", {"counts": pending})

        yield report
        self.limiter.reported(pending)

    def insert_trial(
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
            session_id=self.info.session_id,
            participant=self.info.participant,
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

    def record_abort(self, tx: Transaction, run: TrialRun, *, status: str, note: str) -> None:
        """Record the stopped ``run`` with ``status`` (outcome ``aborted``); no run is active."""
        tx.end_trial(
            run.trial_id,
            status=status,
            outcome="aborted",
            success=False,
            duration_s=run.duration_s(),
            ticks=run.ticks,
            note=note,
        )
        self.state.active = None


__all__ = ["Ledger", "SessionInfo"]

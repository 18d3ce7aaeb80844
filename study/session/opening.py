"""Opening a session: enrolling a new participant (schedule row, assignments) or reopening a
session after a restart or crash (a trial left running is marked interrupted)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Self

from study.schedule import Design, Enrollment, ScheduleError, next_row
from study.session.core import FINAL_STATUSES, SessionCore
from study.session.errors import MAX_SEED, InvalidSeedError, SessionStateError, check_seed
from study.session.plan import run_label
from study.session.sample_writer import DEFAULT_FLUSH_INTERVAL_S
from study.session.store_open import check_protocol
from study.session.trial_run import TrialFactory
from study.store import Store, check_participant_id

if TYPE_CHECKING:
    from study.protocol import Protocol


class SessionOpening(SessionCore):
    """``enrol`` and ``reopen``: the two ways to get a session object."""

    @classmethod
    def enrol(
        cls,
        store: Store,
        protocol: Protocol,
        participant: str,
        *,
        demographics: Mapping[str, Any] | None = None,
        seed: int = 0,
        schedule_row: int | None = None,
        trial_factory: TrialFactory | None = None,
        heartbeat_s: float = 2.0,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
    ) -> Self:
        """Enrol a new participant (pseudonymous ``participant`` ID; ``demographics`` go to their
        own table) and open their session. The schedule row comes from ``study.schedule.next_row``
        over everyone enrolled so far unless given. Raises ``DuplicateParticipantError`` if the ID
        is taken, ``InvalidParticipantIdError`` if it is not a pseudonym, ``InvalidSeedError`` if
        ``seed`` is not in ``0..MAX_SEED`` and ``ScheduleError`` for a negative ``schedule_row``;
        nothing is written then."""
        check_participant_id(participant)
        seed = check_seed(seed)
        if schedule_row is not None and (
            isinstance(schedule_row, bool) or not isinstance(schedule_row, int) or schedule_row < 0
        ):
            raise ScheduleError(
                f"design rows are integers >= 0, got {schedule_row!r}; pass e.g. --schedule-row 0"
                " (or leave it out to take the next row)"
            )
        check_protocol(store, protocol)
        design = Design.from_protocol(protocol)
        with store.transaction() as tx:
            history = tx.enrolment_history()
            if schedule_row is None:
                schedule_row = next_row(
                    Enrollment(p, withdrawn=status == "withdrawn", row=row)
                    for p, row, status in history
                )
            rows = [
                (t.position, t.task, run_label(t.run), t.mode)
                for t in design.row_trials(schedule_row, participant=participant)
            ]
            session_id = tx.enrol(
                participant,
                schedule_row=schedule_row,
                assignments=rows,
                seed=seed,
                demographics=demographics,
            )
            tx.event(
                session_id,
                participant,
                "enrol",
                {"schedule_row": schedule_row, "seed": seed, "demographics": bool(demographics)},
            )
        return cls(
            store=store,
            protocol=protocol,
            participant=participant,
            trial_factory=trial_factory,
            heartbeat_s=heartbeat_s,
            flush_interval_s=flush_interval_s,
        )

    @classmethod
    def reopen(
        cls,
        store: Store,
        protocol: Protocol,
        participant: str,
        *,
        trial_factory: TrialFactory | None = None,
        heartbeat_s: float = 2.0,
        flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S,
    ) -> Self:
        """Continue ``participant``'s session where it stopped. A trial left running by a dead
        process is marked interrupted (its samples up to the last batch kept) and will run again
        as a new attempt. Raises ``UnknownParticipantError``, ``SessionLockedError`` (a live
        process holds it), ``SessionStateError`` (the session already ended) or
        ``InvalidSeedError`` (the store holds a seed no session can run with)."""
        check_protocol(store, protocol)
        record = store.session(participant)
        if record.status in FINAL_STATUSES:
            raise SessionStateError(
                f"participant {participant}'s session is already {record.status}; there is "
                "nothing to resume (enrol a new participant ID for a new session)"
            )
        try:
            check_seed(record.seed)
        except InvalidSeedError:
            raise InvalidSeedError(
                f"participant {participant}'s session was enrolled with seed {record.seed!r}, "
                f"which no session can run with (seeds are 0..{MAX_SEED}), so it cannot be "
                "resumed; its records are kept - enrol the participant under a new ID with a "
                "valid --seed"
            ) from None
        session = cls(
            store=store,
            protocol=protocol,
            participant=participant,
            trial_factory=trial_factory,
            heartbeat_s=heartbeat_s,
            flush_interval_s=flush_interval_s,
        )
        try:
            with session._tx() as tx:
                interrupted = tx.interrupt_running_trials(session.session_id)
                detail: dict[str, Any] = {"cursor": session._cursor, "interrupted": interrupted}
                if session._lease.took_over:
                    detail["took_over"] = session._lease.took_over
                tx.event(session.session_id, participant, "reopen", detail)
        except BaseException:
            session.close()
            raise
        return session


__all__ = ["SessionOpening"]

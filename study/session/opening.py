"""Opening a session: enrolling a new participant (schedule row, assignments) or checking a
session can be reopened after a restart or crash. ``Session.enrol`` and ``Session.reopen``
call these, then bind the session to this process."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from study.protocol import Protocol
from study.schedule import Design, Enrollment, ScheduleError, next_row
from study.session.errors import MAX_SEED, InvalidSeedError, SessionStateError, check_seed
from study.session.plan import run_label
from study.session.state import FINAL_STATUSES
from study.session.store_open import check_protocol
from study.store import Store, check_participant_id


def enrol_participant(
    store: Store,
    protocol: Protocol,
    participant: str,
    *,
    demographics: Mapping[str, Any] | None,
    seed: int,
    schedule_row: int | None,
    recruitment: Mapping[str, str] | None = None,
) -> None:
    """Write ``participant``'s enrolment: schedule row, assignments, seed, and the recruitment
    IDs they came with (in the ``enrol`` event; see ``Session.enrol`` for the errors); nothing
    is written if one is raised."""
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
        detail: dict[str, Any] = {
            "schedule_row": schedule_row,
            "seed": seed,
            "demographics": bool(demographics),
        }
        if recruitment:
            detail["recruitment"] = {str(k): str(v) for k, v in recruitment.items()}
        tx.event(session_id, participant, "enrol", detail)


def check_reopenable(store: Store, protocol: Protocol, participant: str) -> None:
    """Raise unless ``participant``'s session can be continued (see ``Session.reopen``)."""
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


__all__ = ["check_reopenable", "enrol_participant"]

"""``Transaction``: the writes allowed inside one ``Store.transaction()``."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Mapping, Sequence
from typing import Any

from study.store.errors import (
    DuplicateParticipantError,
    SessionLockedError,
    StoreError,
    UnknownParticipantError,
)
from study.store.records import Lease
from study.store.values import (
    SESSION_STATUSES,
    TRIAL_STATUSES,
    check_participant_id,
    now_iso,
    unknown_participant,
)


class Transaction:
    """Writes inside one ``Store.transaction()``; each method is one or two SQL statements."""

    def __init__(self, conn: sqlite3.Connection) -> None:
        self.cur = conn.cursor()

    def require_participant(self, participant: str) -> None:
        row = self.cur.execute(
            "SELECT 1 FROM participants WHERE participant = ?", (participant,)
        ).fetchone()
        if row is None:
            raise UnknownParticipantError(unknown_participant(participant, None))

    def require_lease(self, lease: Lease) -> None:
        """Raise ``SessionLockedError`` unless ``lease`` is still the participant's lease."""
        row = self.cur.execute(
            "SELECT token, pid FROM leases WHERE participant = ?", (lease.participant,)
        ).fetchone()
        if row is None or row[0] != lease.token:
            holder = f"process {row[1]}" if row else "nobody"
            raise SessionLockedError(
                f"participant {lease.participant}'s session lease is now held by {holder}; this "
                "session object must stop writing (reopen it with resume)"
            )

    def enrolment_history(self) -> list[tuple[str, int, str]]:
        """``(participant, schedule_row, session status)`` in enrolment order (read inside the
        enrolling transaction, so two enrolments cannot take the same schedule row)."""
        return [
            (p, int(r), s)
            for p, r, s in self.cur.execute(
                "SELECT p.participant, p.schedule_row, s.status FROM participants p "
                "JOIN sessions s USING (participant) ORDER BY s.session_id"
            ).fetchall()
        ]

    def enrol(
        self,
        participant: str,
        *,
        schedule_row: int,
        assignments: Sequence[tuple[int, str, str, str]],
        seed: int,
        demographics: Mapping[str, Any] | None = None,
    ) -> int:
        """Add a participant, their demographics (own table), schedule and session; returns the
        session id. ``assignments`` rows are ``(position, task, run, mode)``."""
        check_participant_id(participant)
        if self.cur.execute(
            "SELECT 1 FROM participants WHERE participant = ?", (participant,)
        ).fetchone():
            raise DuplicateParticipantError(
                f"participant {participant} is already enrolled; choose a new ID, or resume "
                "their session (--resume)"
            )
        at = now_iso()
        self.cur.execute(
            "INSERT INTO participants VALUES (?, ?, ?)", (participant, at, schedule_row)
        )
        if demographics:
            self.cur.execute(
                "INSERT INTO demographics VALUES (?, ?, ?)",
                (participant, at, json.dumps(dict(demographics), sort_keys=True)),
            )
        self.cur.executemany(
            "INSERT INTO assignments VALUES (?, ?, ?, ?, ?, ?)",
            [
                (participant, pos, task, run, mode, schedule_row)
                for pos, task, run, mode in assignments
            ],
        )
        self.cur.execute(
            "INSERT INTO sessions (participant, created_at, status, cursor, seed) "
            "VALUES (?, ?, 'enrolled', 0, ?)",
            (participant, at, seed),
        )
        return int(self.cur.lastrowid or 0)

    def event(
        self, session_id: int | None, participant: str | None, kind: str, detail: Mapping[str, Any]
    ) -> None:
        """Append an event row. For a participant's session use ``Session.record_event``, which
        also checks the session's lease in the same transaction."""
        self.cur.execute(
            "INSERT INTO events (session_id, participant, at, kind, detail) VALUES (?, ?, ?, ?, ?)",
            (session_id, participant, now_iso(), kind, json.dumps(dict(detail), sort_keys=True)),
        )

    def update_session(
        self, session_id: int, *, cursor: int | None = None, status: str | None = None
    ) -> None:
        """Move the session's cursor and/or status; a final status also stamps ``ended_at``."""
        if status is not None:
            if status not in SESSION_STATUSES:
                raise StoreError(f"session status {status!r} is not one of {SESSION_STATUSES}")
            ended = now_iso() if status in ("completed", "withdrawn", "ended") else None
            self.cur.execute(
                "UPDATE sessions SET status = ?, ended_at = ? WHERE session_id = ?",
                (status, ended, session_id),
            )
        if cursor is not None:
            self.cur.execute(
                "UPDATE sessions SET cursor = ? WHERE session_id = ?", (cursor, session_id)
            )

    def insert_trial(self, **fields: Any) -> int:
        """Insert a trial attempt with status ``running``; returns its ``trial_id``."""
        fields = dict(fields)
        fields.setdefault("status", "running")
        fields.setdefault("started_at", now_iso())
        for key in ("goal_names", "goal_positions"):
            fields[key] = json.dumps(fields.get(key, []))
        cols = ", ".join(fields)
        marks = ", ".join("?" for _ in fields)
        self.cur.execute(f"INSERT INTO trials ({cols}) VALUES ({marks})", tuple(fields.values()))
        return int(self.cur.lastrowid or 0)

    def end_trial(
        self,
        trial_id: int,
        *,
        status: str,
        outcome: str | None,
        success: bool | None,
        duration_s: float | None,
        ticks: int,
        note: str | None = None,
    ) -> None:
        if status not in TRIAL_STATUSES:
            raise StoreError(f"trial status {status!r} is not one of {TRIAL_STATUSES}")
        self.cur.execute(
            "UPDATE trials SET status = ?, outcome = ?, success = ?, duration_s = ?, ticks = ?, "
            "ended_at = ?, note = coalesce(?, note) WHERE trial_id = ?",
            (
                status,
                outcome,
                None if success is None else int(success),
                duration_s,
                ticks,
                now_iso(),
                note,
                trial_id,
            ),
        )

    def set_trial_status(self, trial_id: int, status: str, *, note: str | None = None) -> None:
        if status not in TRIAL_STATUSES:
            raise StoreError(f"trial status {status!r} is not one of {TRIAL_STATUSES}")
        self.cur.execute(
            "UPDATE trials SET status = ?, note = coalesce(?, note) WHERE trial_id = ?",
            (status, note, trial_id),
        )

    def interrupt_running_trials(self, session_id: int) -> list[int]:
        """Mark this session's ``running`` trials (left by a crash) ``interrupted``; their
        ``ticks`` become the number of samples that reached the file."""
        ids = [
            r[0]
            for r in self.cur.execute(
                "SELECT trial_id FROM trials WHERE session_id = ? AND status = 'running'",
                (session_id,),
            ).fetchall()
        ]
        for trial_id in ids:
            n, last_t = self.cur.execute(
                "SELECT count(*), max(t) FROM samples WHERE trial_id = ?", (trial_id,)
            ).fetchone()
            self.cur.execute(
                "UPDATE trials SET status = 'interrupted', outcome = 'interrupted', success = 0, "
                "ticks = ?, duration_s = ?, ended_at = ?, "
                "note = coalesce(note, 'process ended during the trial') WHERE trial_id = ?",
                (n, last_t, now_iso(), trial_id),
            )
        return ids

    def add_rating(
        self,
        *,
        session_id: int,
        participant: str,
        step: int,
        phase: str,
        task: str | None,
        mode: str | None,
        run: str | None,
        trial_id: int | None,
        item: str,
        value: int,
    ) -> None:
        self.cur.execute(
            "INSERT INTO ratings (session_id, participant, step, phase, task, mode, run, trial_id, "
            "item, value, answered_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (
                session_id,
                participant,
                step,
                phase,
                task,
                mode,
                run,
                trial_id,
                item,
                value,
                now_iso(),
            ),
        )

    def add_answer(
        self,
        *,
        session_id: int,
        participant: str,
        step: int,
        questionnaire: str,
        item: str,
        kind: str,
        value: str | None,
        number: float | None = None,
    ) -> None:
        """One answer to a non-Likert item (``AnswerRecord``)."""
        self.cur.execute(
            "INSERT INTO answers (session_id, participant, step, questionnaire, item, kind, "
            "value, number, answered_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (session_id, participant, step, questionnaire, item, kind, value, number, now_iso()),
        )

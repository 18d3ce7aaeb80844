"""What a ``Store`` reads: participants, sessions, trials, samples, ratings, answers, events and
whole tables, each a typed record or a DataFrame.

A trial the file says is ``running`` although no live process runs it is reported
``interrupted`` (``study.store.orphans``) without writing to the file; several reads that must
agree run in one read transaction (``_snapshot``).
"""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pandas as pd

from study.store import opening
from study.store.errors import StoreError, UnknownParticipantError
from study.store.orphans import ORPHAN_NOTE, STALE_AFTER_S, Orphan, orphaned_trials
from study.store.records import (
    AnswerRecord,
    AssignmentRecord,
    EventRecord,
    ParticipantRecord,
    RatingRecord,
    SessionRecord,
    TrialRecord,
)
from study.store.schema import ANSWER_COLUMNS, SAMPLE_COLUMNS, TABLES
from study.store.values import unknown_participant


class Readers:
    """The reading half of ``Store`` (a mixin: it uses the store's connection and lock)."""

    # what it needs of the Store it is mixed into (declared, not defined here)
    path: Path
    _lock: threading.RLock
    conn: sqlite3.Connection

    def _query(self, sql: str, params: Sequence[Any] = ()) -> list[tuple[Any, ...]]:
        with self._lock:
            return self.conn.execute(sql, params).fetchall()

    def participants(self) -> list[ParticipantRecord]:
        return [ParticipantRecord(*r) for r in self._query("SELECT * FROM participants ORDER BY 2")]

    def participant(self, participant: str) -> ParticipantRecord:
        """The participant's row; ``UnknownParticipantError`` if not enrolled."""
        rows = self._query("SELECT * FROM participants WHERE participant = ?", (participant,))
        if not rows:
            raise UnknownParticipantError(unknown_participant(participant, self.path))
        return ParticipantRecord(*rows[0])

    def has_participant(self, participant: str) -> bool:
        return bool(self._query("SELECT 1 FROM participants WHERE participant = ?", (participant,)))

    def demographics(self, participant: str) -> dict[str, Any] | None:
        rows = self._query("SELECT data FROM demographics WHERE participant = ?", (participant,))
        return json.loads(rows[0][0]) if rows else None

    def session(self, participant: str) -> SessionRecord:
        """The participant's session; ``UnknownParticipantError`` if not enrolled."""
        rows = self._query("SELECT * FROM sessions WHERE participant = ?", (participant,))
        if not rows:
            raise UnknownParticipantError(unknown_participant(participant, self.path))
        return SessionRecord(*rows[0])

    def sessions(self) -> list[SessionRecord]:
        return [SessionRecord(*r) for r in self._query("SELECT * FROM sessions ORDER BY 1")]

    def assignments(self, participant: str) -> list[AssignmentRecord]:
        rows = self._query(
            "SELECT * FROM assignments WHERE participant = ? ORDER BY position", (participant,)
        )
        return [AssignmentRecord(*r) for r in rows]

    def trials(
        self, *, participant: str | None = None, session_id: int | None = None, raw: bool = False
    ) -> list[TrialRecord]:
        """Trial attempts in the order they started (optionally of one participant/session).

        A trial left ``running`` by a dead process is reported ``interrupted`` (see
        ``study.store.orphans``); ``raw=True`` returns the rows exactly as stored."""
        sql, params = _where("SELECT * FROM trials", participant=participant, session_id=session_id)
        with self._snapshot() as conn:
            rows = conn.execute(sql + " ORDER BY trial_id", params).fetchall()
            orphans = {} if raw else orphaned_trials(conn, stale_after_s=STALE_AFTER_S)
        return [_settled(_trial(r), orphans) for r in rows]

    def trial(self, trial_id: int, *, raw: bool = False) -> TrialRecord:
        """One trial attempt (an orphaned ``running`` one reported as in ``trials``)."""
        with self._snapshot() as conn:
            rows = conn.execute("SELECT * FROM trials WHERE trial_id = ?", (trial_id,)).fetchall()
            orphans = {} if raw or not rows else orphaned_trials(conn)
        if not rows:
            raise StoreError(f"no trial with id {trial_id} in {self.path}")
        return _settled(_trial(rows[0]), orphans)

    def sample_count(self, trial_id: int) -> int:
        return int(
            self._query("SELECT count(*) FROM samples WHERE trial_id = ?", (trial_id,))[0][0]
        )

    def samples(self, trial_id: int | None = None) -> pd.DataFrame:
        """Sample rows (``SAMPLE_COLUMNS``) ordered by trial and tick; ``probabilities`` and
        ``events`` stay JSON text (``app.trial.events.decode_events`` reads events). A column
        the file predates (opened read-only) reads as empty."""
        with self._lock:
            have = opening.sample_columns(self.conn)
        columns = (c if c in have else f"NULL AS {c}" for c in SAMPLE_COLUMNS)
        sql = f"SELECT {', '.join(columns)} FROM samples"
        params: tuple[Any, ...] = ()
        if trial_id is not None:
            sql += " WHERE trial_id = ?"
            params = (trial_id,)
        with self._lock:
            return pd.read_sql_query(sql + " ORDER BY trial_id, tick", self.conn, params=params)

    def ratings(
        self, *, participant: str | None = None, session_id: int | None = None
    ) -> list[RatingRecord]:
        sql, params = _where(
            "SELECT * FROM ratings", participant=participant, session_id=session_id
        )
        return [RatingRecord(*r) for r in self._query(sql + " ORDER BY rating_id", params)]

    def answers(
        self, *, participant: str | None = None, session_id: int | None = None
    ) -> list[AnswerRecord]:
        """Answers to the non-Likert items (an older store read-only has none)."""
        if "answers" not in self._tables():
            return []
        sql, params = _where(
            "SELECT * FROM answers", participant=participant, session_id=session_id
        )
        return [AnswerRecord(*r) for r in self._query(sql + " ORDER BY answer_id", params)]

    def events(
        self, *, participant: str | None = None, session_id: int | None = None
    ) -> list[EventRecord]:
        sql, params = _where("SELECT * FROM events", participant=participant, session_id=session_id)
        rows = self._query(sql + " ORDER BY event_id", params)
        return [EventRecord(*r[:5], detail=json.loads(r[5])) for r in rows]

    def frame(self, table: str, *, raw: bool = False) -> pd.DataFrame:
        """A whole table as a DataFrame (for export; ``leases`` included for diagnostics).

        In ``trials``, orphaned ``running`` trials are reported as in ``trials()`` unless
        ``raw``."""
        if table not in TABLES:
            raise StoreError(f"unknown table {table!r}; tables are {', '.join(TABLES)}")
        if table == "protocols" and "protocols" not in self._tables():
            return pd.DataFrame(
                columns=["content_hash", "protocol_id", "protocol_version", "text", "recorded_at"]
            )
        if table == "answers" and "answers" not in self._tables():
            return pd.DataFrame(columns=list(ANSWER_COLUMNS))
        with self._snapshot() as conn:
            df = pd.read_sql_query(f"SELECT * FROM {table}", conn)
            orphans = orphaned_trials(conn) if table == "trials" and not raw else {}
        for trial_id, orphan in orphans.items():
            row = df["trial_id"] == trial_id
            df.loc[row, ["status", "outcome", "success"]] = ["interrupted", "interrupted", 0]
            df.loc[row, ["ticks", "duration_s"]] = [orphan.ticks, orphan.duration_s]
            df.loc[row & df["note"].isna(), "note"] = ORPHAN_NOTE
        return df

    def orphaned_trials(self) -> list[int]:
        """Ids of trials the file says are ``running`` although no live process runs them
        (reported ``interrupted`` by the readers; resuming the session records it)."""
        with self._snapshot() as conn:
            return sorted(orphaned_trials(conn))

    def _tables(self) -> set[str]:
        return {r[0] for r in self._query("SELECT name FROM sqlite_master WHERE type='table'")}

    @contextmanager
    def _snapshot(self) -> Iterator[sqlite3.Connection]:
        """Several reads that see one consistent state of the file (one read transaction)."""
        with self._lock:
            conn = self.conn
            if conn.in_transaction:  # inside this store's own write: already consistent
                yield conn
                return
            conn.execute("BEGIN")
            try:
                yield conn
            finally:
                conn.execute("COMMIT")

    def integrity_check(self) -> str:
        """SQLite's ``PRAGMA integrity_check`` result (``"ok"`` for a healthy file)."""
        return "\n".join(r[0] for r in self._query("PRAGMA integrity_check"))


def _where(
    sql: str, *, participant: str | None, session_id: int | None
) -> tuple[str, tuple[Any, ...]]:
    clauses, params = [], []
    if participant is not None:
        clauses.append("participant = ?")
        params.append(participant)
    if session_id is not None:
        clauses.append("session_id = ?")
        params.append(session_id)
    if clauses:
        sql += " WHERE " + " AND ".join(clauses)
    return sql, tuple(params)


def _settled(record: TrialRecord, orphans: Mapping[int, Orphan]) -> TrialRecord:
    """``record`` as readers report it: an orphaned ``running`` trial becomes interrupted."""
    orphan = orphans.get(record.trial_id)
    if orphan is None or record.status != "running":
        return record
    return dataclasses.replace(
        record,
        status="interrupted",
        outcome="interrupted",
        success=False,
        ticks=orphan.ticks,
        duration_s=orphan.duration_s,
        note=record.note or ORPHAN_NOTE,
    )


def _trial(row: Sequence[Any]) -> TrialRecord:
    values = list(row)
    data = dict(zip([f.name for f in dataclasses.fields(TrialRecord)], values, strict=True))
    data["success"] = None if data["success"] is None else bool(data["success"])
    data["goal_names"] = json.loads(data["goal_names"])
    data["goal_positions"] = json.loads(data["goal_positions"])
    return TrialRecord(**data)

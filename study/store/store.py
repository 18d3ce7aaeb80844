"""``Store``: the study's SQLite database (WAL, versioned schema, one file per study).

Thread-safety: every public method of ``Store`` and ``Transaction`` is thread-safe. The store
owns one connection guarded by a re-entrant lock; a ``with store.transaction()`` block holds the
lock from ``BEGIN IMMEDIATE`` to ``COMMIT``, so writes from the session (viser callback threads)
and the sample writer thread serialise, and other processes wait on SQLite's own lock
(``busy_timeout``). Nothing here blocks a control loop that only hands rows to a
``SampleWriter``.

Opening never alters a file it refuses: the schema version and the protocol (study id + content
hash) are checked read-only before any pragma that writes. The store keeps the full text of the
protocol it was created for (``protocol_text()``); a ``running`` trial whose process is dead is
read back as ``interrupted`` (``study.store.orphans``) without writing to the file.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import sqlite3
import threading
import time
import tomllib
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd

from study.store import lease as lease_mod
from study.store.errors import (
    DuplicateParticipantError,
    InvalidParticipantIdError,
    NotAStoreError,
    ProtocolMismatchError,
    ReadOnlyStoreError,
    SchemaVersionError,
    SessionLockedError,
    StoreError,
    UnknownParticipantError,
)
from study.store.orphans import ORPHAN_NOTE, STALE_AFTER_S, Orphan, orphaned_trials
from study.store.records import (
    AssignmentRecord,
    EventRecord,
    Lease,
    ParticipantRecord,
    RatingRecord,
    SessionRecord,
    StoreMeta,
    TrialRecord,
)
from study.store.schema import (
    DDL,
    MIGRATIONS,
    READABLE_VERSIONS,
    SAMPLE_COLUMNS,
    SCHEMA_VERSION,
    TABLES,
)

PARTICIPANT_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,31}$")
SESSION_STATUSES = ("enrolled", "running", "completed", "withdrawn", "ended")
TRIAL_STATUSES = ("running", "completed", "redone", "skipped", "interrupted")
_INSERT_SAMPLE = (
    f"INSERT INTO samples ({', '.join(SAMPLE_COLUMNS)}) "
    f"VALUES ({', '.join('?' for _ in SAMPLE_COLUMNS)})"
)


def now_iso() -> str:
    """The current UTC time, ISO 8601 with microseconds (the store's timestamp format)."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


def check_participant_id(participant: str) -> str:
    """Return ``participant`` if it is a valid pseudonym, else raise ``InvalidParticipantIdError``."""
    if not isinstance(participant, str) or not PARTICIPANT_ID.match(participant):
        raise InvalidParticipantIdError(
            f"participant ID {participant!r} is not a pseudonym: use 1-32 letters, digits, '-' "
            "or '_', starting with a letter or digit (e.g. 'P01'); never a name or e-mail"
        )
    return participant


class Store:
    """A study database. Open with ``Store.open`` (read-write, protocol checked) or
    ``Store.open_readonly`` (export and analysis; any protocol)."""

    def __init__(
        self, conn: sqlite3.Connection, *, path: Path, meta: StoreMeta, readonly: bool
    ) -> None:
        self._conn = conn
        self._lock = threading.RLock()
        self.path = path
        self.meta = meta
        self.readonly = readonly

    # ---- opening --------------------------------------------------------------------------
    @classmethod
    def open(
        cls,
        path: str | os.PathLike[str],
        *,
        protocol_id: str,
        protocol_hash: str,
        protocol_version: str = "",
        protocol_text: str | None = None,
        synchronous: str = "FULL",
        busy_timeout_s: float = 10.0,
    ) -> Store:
        """Open (or create) the store at ``path`` for the protocol ``protocol_id``/``protocol_hash``.

        ``protocol_text`` is the protocol's TOML source (``study.session.open_store`` always
        passes it): it is kept in the ``protocols`` table, keyed by the hash, when the store is
        created (or later, if the store has no text for this hash yet), so export and analysis
        can rebuild the exact protocol. Raises ``SchemaVersionError`` or
        ``ProtocolMismatchError`` if the file was written by another schema or protocol,
        ``NotAStoreError`` if it is not a study store. The file is only read before these checks
        pass; a version-1 file is then upgraded in place (it gains the ``protocols`` table).
        ``synchronous`` is SQLite's durability level (``FULL``: every commit survives power
        loss; ``NORMAL``: survives a killed process).
        """
        if synchronous not in ("FULL", "NORMAL"):
            raise StoreError(f"synchronous must be 'FULL' or 'NORMAL', not {synchronous!r}")
        p = Path(path)
        if p.parent and not p.parent.exists():
            raise StoreError(f"cannot create store {p}: directory {p.parent} does not exist")
        conn = _connect(p, readonly=False, busy_timeout_s=busy_timeout_s)
        try:
            meta = _read_meta(conn, p)
            if meta is None:
                meta = _create(conn, p, protocol_id, protocol_version, protocol_hash)
            _check_protocol(
                meta,
                p,
                protocol_id,
                protocol_hash,
                protocol_version,
                protocol_text,
                _stored_text(conn, meta.protocol_hash),
            )
            conn.execute("PRAGMA journal_mode=WAL")
            conn.execute(f"PRAGMA synchronous={synchronous}")
            conn.execute("PRAGMA foreign_keys=ON")
            meta = _migrate(conn, meta)
            if protocol_text is not None and _stored_text(conn, protocol_hash) is None:
                _record_protocol(conn, meta, protocol_text)
        except BaseException:
            conn.close()
            raise
        return cls(conn, path=p, meta=meta, readonly=False)

    @classmethod
    def open_readonly(cls, path: str | os.PathLike[str]) -> Store:
        """Open an existing store for reading only (any protocol; the schema version must match)."""
        p = Path(path)
        if not p.exists():
            raise StoreError(f"no store at {p}: check the --db path")
        conn = _connect(p, readonly=True, busy_timeout_s=10.0)
        try:
            meta = _read_meta(conn, p)
            if meta is None:
                raise NotAStoreError(f"{p} is an empty SQLite file, not a study store")
        except BaseException:
            conn.close()
            raise
        return cls(conn, path=p, meta=meta, readonly=True)

    def close(self) -> None:
        """Close the connection (idempotent)."""
        with self._lock:
            if self._conn is not None:
                self._conn.close()
                self._conn = None  # type: ignore[assignment]

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def conn(self) -> sqlite3.Connection:
        if self._conn is None:
            raise StoreError(f"store {self.path} is closed")
        return self._conn

    def protocol_text(self) -> str | None:
        """The TOML text of the protocol this store was created for (``None`` for a store made
        without it, e.g. by a schema-1 version of the platform). Rebuild the ``Protocol`` with
        ``study.protocol.protocol_from_store(store)``, which also checks its content hash."""
        with self._lock:
            return _stored_text(self.conn, self.meta.protocol_hash)

    # ---- writing ----------------------------------------------------------------------------
    @contextmanager
    def transaction(self) -> Iterator[Transaction]:
        """``with store.transaction() as tx:`` one atomic write (``BEGIN IMMEDIATE`` .. ``COMMIT``).

        Any exception rolls everything back and propagates; SQLite's own errors (locked after
        ``busy_timeout``, disk full, constraint violations) come out as ``StoreError``."""
        if self.readonly:
            raise ReadOnlyStoreError(f"store {self.path} was opened read-only")
        with self._lock:
            conn = self.conn
            if conn.in_transaction:
                raise StoreError(
                    "store transactions do not nest: commit the open one before starting another"
                )
            try:
                conn.execute("BEGIN IMMEDIATE")
                try:
                    yield Transaction(conn)
                    conn.execute("COMMIT")
                except BaseException:
                    if conn.in_transaction:
                        conn.execute("ROLLBACK")
                    raise
            except sqlite3.Error as exc:
                raise StoreError(
                    f"store {self.path}: {exc} (nothing of this write was kept)"
                ) from exc

    def insert_samples(self, rows: Sequence[Sequence[Any]]) -> None:
        """Insert sample rows (``SAMPLE_COLUMNS`` order) in one transaction with ``executemany``."""
        if not rows:
            return
        with self.transaction() as tx:
            tx.cur.executemany(_INSERT_SAMPLE, rows)

    # ---- leases -------------------------------------------------------------------------------
    def acquire_lease(self, participant: str, *, stale_after_s: float = STALE_AFTER_S) -> Lease:
        """Claim ``participant``'s session for this process.

        Raises ``SessionLockedError`` while a live process (or another session object in this
        process) holds it. A lease left by a dead process is taken over; ``Lease.took_over``
        then describes it."""
        token = uuid.uuid4().hex
        pid = os.getpid()
        with self.transaction() as tx:
            tx.require_participant(participant)
            row = tx.cur.execute(
                "SELECT token, pid, host, process_start, acquired_at, heartbeat_at FROM leases "
                "WHERE participant = ?",
                (participant,),
            ).fetchone()
            took_over = None
            if row is not None:
                _, holder_pid, host, started, acquired_at, heartbeat_at = row
                age = time.time() - heartbeat_at
                if (host == lease_mod.HOST and holder_pid == pid) or lease_mod.holder_is_live(
                    pid=holder_pid,
                    host=host,
                    started=started,
                    heartbeat_age_s=age,
                    stale_after_s=stale_after_s,
                ):
                    where = "this process" if holder_pid == pid else f"process {holder_pid}"
                    raise SessionLockedError(
                        f"participant {participant}'s session is already open in {where} on "
                        f"{host} (since {acquired_at}, last heartbeat {age:.1f} s ago); close it "
                        "there first, or wait for that process to exit"
                    )
                took_over = {"pid": holder_pid, "host": host, "acquired_at": acquired_at}
            tx.cur.execute(
                "INSERT OR REPLACE INTO leases VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    participant,
                    token,
                    pid,
                    lease_mod.HOST,
                    lease_mod.process_start(pid),
                    now_iso(),
                    time.time(),
                ),
            )
        return Lease(participant=participant, token=token, pid=pid, took_over=took_over)

    def heartbeat(self, lease: Lease) -> None:
        """Refresh ``lease``; raises ``SessionLockedError`` if another process took it over."""
        with self.transaction() as tx:
            tx.cur.execute(
                "UPDATE leases SET heartbeat_at = ? WHERE participant = ? AND token = ?",
                (time.time(), lease.participant, lease.token),
            )
            if tx.cur.rowcount != 1:
                raise SessionLockedError(
                    f"participant {lease.participant}'s session lease was taken over by another "
                    "process; this process must stop writing"
                )

    def release_lease(self, lease: Lease) -> None:
        """Give the session back (no error if it was already released)."""
        with self.transaction() as tx:
            tx.cur.execute(
                "DELETE FROM leases WHERE participant = ? AND token = ?",
                (lease.participant, lease.token),
            )

    # ---- reading -------------------------------------------------------------------------------
    def _query(self, sql: str, params: Sequence[Any] = ()) -> list[tuple[Any, ...]]:
        with self._lock:
            return self.conn.execute(sql, params).fetchall()

    def participants(self) -> list[ParticipantRecord]:
        return [ParticipantRecord(*r) for r in self._query("SELECT * FROM participants ORDER BY 2")]

    def participant(self, participant: str) -> ParticipantRecord:
        """The participant's row; ``UnknownParticipantError`` if not enrolled."""
        rows = self._query("SELECT * FROM participants WHERE participant = ?", (participant,))
        if not rows:
            raise UnknownParticipantError(_unknown(participant, self.path))
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
            raise UnknownParticipantError(_unknown(participant, self.path))
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
        ``events`` stay JSON text (expand them with ``json.loads``)."""
        sql = f"SELECT {', '.join(SAMPLE_COLUMNS)} FROM samples"
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


class Transaction:
    """Writes inside one ``Store.transaction()``; each method is one or two SQL statements."""

    def __init__(self, conn: sqlite3.Connection) -> None:
        self.cur = conn.cursor()

    def require_participant(self, participant: str) -> None:
        row = self.cur.execute(
            "SELECT 1 FROM participants WHERE participant = ?", (participant,)
        ).fetchone()
        if row is None:
            raise UnknownParticipantError(_unknown(participant, None))

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


# ---- helpers ------------------------------------------------------------------------------------
def _connect(path: Path, *, readonly: bool, busy_timeout_s: float) -> sqlite3.Connection:
    uri = f"file:{path.resolve()}?mode={'ro' if readonly else 'rwc'}"
    try:
        conn = sqlite3.connect(
            uri, uri=True, isolation_level=None, check_same_thread=False, timeout=busy_timeout_s
        )
    except sqlite3.Error as exc:
        raise StoreError(f"cannot open store {path}: {exc}") from exc
    return conn


def _read_meta(conn: sqlite3.Connection, path: Path) -> StoreMeta | None:
    """The file's ``schema_version`` row, ``None`` for an empty file; errors for anything else."""
    try:
        names = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    except sqlite3.DatabaseError as exc:
        raise NotAStoreError(
            f"{path} is not a SQLite database ({exc}); choose another --db path"
        ) from exc
    if not names:
        return None
    if "schema_version" not in names:
        raise NotAStoreError(
            f"{path} is a SQLite database but not a study store (no schema_version table); "
            "choose another --db path"
        )
    row = conn.execute("SELECT * FROM schema_version").fetchone()
    if row is None:
        raise NotAStoreError(f"{path} has an empty schema_version table; it is not a usable store")
    try:
        meta = StoreMeta(*row)
    except TypeError as exc:
        raise SchemaVersionError(
            f"{path} has a schema_version table of another layout; it was written by other code"
        ) from exc
    if meta.version not in READABLE_VERSIONS:
        raise SchemaVersionError(
            f"{path} uses store schema version {meta.version}, this code reads versions "
            f"{', '.join(map(str, READABLE_VERSIONS))}; open it with the version of the platform "
            "that wrote it (data untouched)"
        )
    return meta


def _migrate(conn: sqlite3.Connection, meta: StoreMeta) -> StoreMeta:
    """Bring an older (readable) file to ``SCHEMA_VERSION`` in one transaction."""
    if meta.version == SCHEMA_VERSION:
        return meta
    conn.execute("BEGIN IMMEDIATE")
    try:
        version = conn.execute("SELECT version FROM schema_version").fetchone()[0]
        while version < SCHEMA_VERSION:  # another process may have migrated meanwhile
            for statement in MIGRATIONS[version]:
                conn.execute(statement)
            version += 1
        conn.execute("UPDATE schema_version SET version = ?", (version,))
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        raise
    return dataclasses.replace(meta, version=SCHEMA_VERSION)


def _stored_text(conn: sqlite3.Connection, content_hash: str) -> str | None:
    try:
        row = conn.execute(
            "SELECT text FROM protocols WHERE content_hash = ?", (content_hash,)
        ).fetchone()
    except sqlite3.OperationalError:  # a schema-1 file: no protocols table
        return None
    return None if row is None else str(row[0])


def _record_protocol(conn: sqlite3.Connection, meta: StoreMeta, text: str) -> None:
    conn.execute(
        "INSERT OR IGNORE INTO protocols VALUES (?, ?, ?, ?, ?)",
        (meta.protocol_hash, meta.protocol_id, meta.protocol_version, text, now_iso()),
    )


def _create(
    conn: sqlite3.Connection,
    path: Path,
    protocol_id: str,
    protocol_version: str,
    protocol_hash: str,
) -> StoreMeta:
    """Create the schema in an empty file (or read the meta of a store a racing process made)."""
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("BEGIN IMMEDIATE")
    try:
        existing = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
        if existing:  # another process created it between our check and our lock
            conn.execute("ROLLBACK")
            meta = _read_meta(conn, path)
            assert meta is not None
            return meta
        for statement in DDL.split(";"):
            if statement.strip():
                conn.execute(statement)
        meta = StoreMeta(SCHEMA_VERSION, protocol_id, protocol_version, protocol_hash, now_iso())
        conn.execute(
            "INSERT INTO schema_version VALUES (?, ?, ?, ?, ?)",
            (meta.version, meta.protocol_id, meta.protocol_version, protocol_hash, meta.created_at),
        )
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        raise
    return meta


def _check_protocol(
    meta: StoreMeta,
    path: Path,
    protocol_id: str,
    protocol_hash: str,
    protocol_version: str,
    text: str | None,
    stored: str | None,
) -> None:
    if meta.protocol_id == protocol_id and meta.protocol_hash == protocol_hash:
        return
    changed = changed_sections(stored, text)
    kept = (
        "; the store keeps the original (`python -m study export` writes it as protocol.toml)"
        if stored is not None
        else ""
    )
    raise ProtocolMismatchError(
        f"{path} was written by protocol {meta.protocol_id!r} version "
        f"{meta.protocol_version or '?'} (content hash {meta.protocol_hash}), not by "
        f"{protocol_id!r} version {protocol_version or '?'} (content hash {protocol_hash})"
        f"{f'; changed: {changed}' if changed else ''}. A store holds one protocol: to continue "
        f"this study use the protocol file it started with{kept}; to run the edited protocol use "
        "a new --db (data untouched)"
    )


def changed_sections(old: str | None, new: str | None, *, limit: int = 8) -> str:
    """Dotted keys (to two levels, e.g. ``modes.aggressive``) whose content differs between two
    protocol texts, comma-separated; ``""`` if either is missing or not TOML."""
    if old is None or new is None:
        return ""
    try:
        a, b = tomllib.loads(old), tomllib.loads(new)
    except tomllib.TOMLDecodeError:
        return ""
    keys: list[str] = []
    for key in sorted(set(a) | set(b)):
        x, y = a.get(key), b.get(key)
        if x == y:
            continue
        if isinstance(x, dict) and isinstance(y, dict):
            keys += [f"{key}.{k}" for k in sorted(set(x) | set(y)) if x.get(k) != y.get(k)]
        else:
            keys.append(key)
    more = f" (+{len(keys) - limit} more)" if len(keys) > limit else ""
    return ", ".join(keys[:limit]) + more


def _unknown(participant: str, path: Path | None) -> str:
    where = f" in {path}" if path else ""
    return (
        f"participant {participant} is not enrolled{where}; check the ID, or start a new "
        "session without --resume to enrol them"
    )


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

"""``Store``: the study's SQLite database (WAL, versioned schema, one file per study).

Writes go through ``with store.transaction() as tx`` (``study.store.transaction``); opening,
schema checks and upgrades are in ``study.store.opening``.

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
import sqlite3
import threading
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pandas as pd

from study.store import faults, opening
from study.store import lease as lease_mod
from study.store.errors import (
    NotAStoreError,
    ReadOnlyStoreError,
    SessionLockedError,
    StoreError,
    StoreNotWritableError,
    StoreWriteError,
    UnknownParticipantError,
)
from study.store.orphans import ORPHAN_NOTE, STALE_AFTER_S, Orphan, orphaned_trials
from study.store.records import (
    AnswerRecord,
    AssignmentRecord,
    EventRecord,
    Lease,
    ParticipantRecord,
    RatingRecord,
    SessionRecord,
    StoreMeta,
    TrialRecord,
)
from study.store.schema import ANSWER_COLUMNS, SAMPLE_COLUMNS, TABLES
from study.store.transaction import Transaction
from study.store.values import now_iso, unknown_participant

_INSERT_SAMPLE = (
    f"INSERT INTO samples ({', '.join(SAMPLE_COLUMNS)}) "
    f"VALUES ({', '.join('?' for _ in SAMPLE_COLUMNS)})"
)


class Store:
    """A study database. Open with ``Store.open`` (read-write, protocol checked) or
    ``Store.open_readonly`` (export and analysis; any protocol)."""

    def __init__(
        self,
        conn: sqlite3.Connection,
        *,
        path: Path,
        meta: StoreMeta,
        readonly: bool,
        busy_timeout_s: float = 10.0,
    ) -> None:
        self._conn = conn
        self._lock = threading.RLock()
        self._samples_conn: sqlite3.Connection | None = None
        self._samples_lock = threading.Lock()
        self._busy_timeout_s = busy_timeout_s
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
        verify: bool = True,
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
        loss; ``NORMAL``: survives a killed process). An existing file is first checked by
        SQLite (``opening.check_integrity``, unless ``verify`` is False -- a worker process
        opening a store its parent just checked): a damaged one raises ``StoreDamagedError``
        and is never written to.
        """
        if synchronous not in ("FULL", "NORMAL"):
            raise StoreError(f"synchronous must be 'FULL' or 'NORMAL', not {synchronous!r}")
        p = Path(path)
        if p.parent and not p.parent.exists():
            raise StoreError(f"cannot create store {p}: directory {p.parent} does not exist")
        # Before SQLite: it reports a folder it cannot write its journal into as "unable to open
        # database file", which reads like a damaged store.
        faults.check_writable(p)
        conn = opening.connect(p, readonly=False, busy_timeout_s=busy_timeout_s)
        try:
            meta = opening.read_meta(conn, p)
            if meta is None:
                meta = opening.create_schema(conn, p, protocol_id, protocol_version, protocol_hash)
            elif verify:
                opening.check_integrity(conn, p)
            opening.check_protocol(
                meta,
                p,
                protocol_id,
                protocol_hash,
                protocol_version,
                protocol_text,
                opening.stored_text(conn, meta.protocol_hash),
            )
            conn.execute("PRAGMA journal_mode=WAL")
            conn.execute(f"PRAGMA synchronous={synchronous}")
            conn.execute("PRAGMA foreign_keys=ON")
            meta = opening.migrate(conn, meta)
            opening.add_sample_columns(conn)
            if protocol_text is not None and opening.stored_text(conn, protocol_hash) is None:
                opening.record_protocol(conn, meta, protocol_text)
        except sqlite3.Error as exc:  # a disk that fills up or turns read-only while opening
            conn.close()
            raise faults.write_error(p, exc) from exc
        except BaseException:
            conn.close()
            raise
        return cls(conn, path=p, meta=meta, readonly=False, busy_timeout_s=busy_timeout_s)

    @classmethod
    def open_readonly(cls, path: str | os.PathLike[str], *, verify: bool = False) -> Store:
        """Open an existing store for reading only (any protocol; the schema version must match);
        ``verify``: check it first like ``open`` does (export does; ``StoreDamagedError``)."""
        p = Path(path)
        if not p.exists():
            raise StoreError(f"no store at {p}: the file does not exist; check the store path")
        conn = opening.connect(p, readonly=True, busy_timeout_s=10.0)
        try:
            try:
                meta = opening.read_meta(conn, p)
            except StoreWriteError:
                # SQLite could not create the journal index (-shm) beside the file: a store in
                # a read-only folder. Nobody can write there, so read it as immutable -- unless
                # a journal (-wal) holds commits that reading the file alone would miss.
                conn.close()
                wal = p.with_name(p.name + "-wal")
                if faults.folder_problem(p.parent) is None:
                    raise
                if wal.exists() and wal.stat().st_size > 0:
                    raise StoreNotWritableError(
                        f"{p} lies in a read-only folder beside its journal {wal.name}, which "
                        "holds commits SQLite cannot merge here; copy the folder (all "
                        f"{p.name}* files) somewhere writable and read the copy",
                        path=p,
                    ) from None
                conn = opening.connect(p, readonly=True, busy_timeout_s=10.0, immutable=True)
                meta = opening.read_meta(conn, p)
            if meta is None:
                raise NotAStoreError(f"{p} is an empty SQLite file, not a study store")
            if verify:
                opening.check_integrity(conn, p)
        except BaseException:
            conn.close()
            raise
        return cls(conn, path=p, meta=meta, readonly=True)

    def close(self) -> None:
        """Close the connection (idempotent)."""
        with self._lock, self._samples_lock:
            if self._samples_conn is not None:
                self._samples_conn.close()
                self._samples_conn = None
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
            return opening.stored_text(self.conn, self.meta.protocol_hash)

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
            except sqlite3.Error as exc:  # disk full, read-only, locked, constraint
                raise faults.write_error(self.path, exc) from exc

    def insert_samples(self, rows: Sequence[Sequence[Any]]) -> None:
        """Insert sample rows (``SAMPLE_COLUMNS`` order) in one transaction with ``executemany``.

        Samples go through a second connection of their own, with ``synchronous=NORMAL``: a
        batch's commit does not wait for the session's lock (held through other commits) and
        does not fsync. Durability given up, and why it is bounded: a killed process loses
        nothing committed (the WAL is in the OS's cache), but a power cut or OS crash may lose
        the sample batches committed since the WAL was last synced -- and every commit of the
        main connection (``synchronous=FULL`` by default) syncs it, including the earlier
        batches: each session's lease heartbeat (every 2 s), every trial end (after its samples
        are flushed), answer and event. Several concurrent sessions each fsyncing ten times a
        second held sample batches up to a second apart on a loaded 2-core machine."""
        if not rows:
            return
        if self.readonly:
            raise ReadOnlyStoreError(f"store {self.path} was opened read-only")
        with self._samples_lock:
            conn = self._sample_connection()
            try:
                conn.execute("BEGIN IMMEDIATE")
                try:
                    conn.executemany(_INSERT_SAMPLE, rows)
                    conn.execute("COMMIT")
                except BaseException:
                    if conn.in_transaction:
                        conn.execute("ROLLBACK")
                    raise
            except sqlite3.Error as exc:
                raise faults.write_error(self.path, exc) from exc

    def _sample_connection(self) -> sqlite3.Connection:
        """The samples' own connection (opened on first use; see ``insert_samples``)."""
        if self._samples_conn is None:
            if self._conn is None:
                raise StoreError(f"store {self.path} is closed")
            conn = opening.connect(self.path, readonly=False, busy_timeout_s=self._busy_timeout_s)
            try:
                conn.execute("PRAGMA synchronous=NORMAL")
                conn.execute("PRAGMA foreign_keys=ON")
                # Checkpoints (copying the WAL into the file, with fsyncs) run on the main
                # connection's commits -- a heartbeat at least every 2 s per session -- never
                # inside a sample batch's commit, which the next batch would wait for.
                conn.execute("PRAGMA wal_autocheckpoint=0")
            except sqlite3.Error as exc:
                conn.close()
                raise faults.write_error(self.path, exc) from exc
            self._samples_conn = conn
        return self._samples_conn

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
            took_over = _require_no_live_holder(tx, participant, stale_after_s=stale_after_s)
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

    def discard_participant(
        self, participant: str, *, stale_after_s: float = STALE_AFTER_S
    ) -> dict[str, int]:
        """Delete everything stored for ``participant`` (samples, trials, ratings, answers, events,
        schedule, session, demographics, enrolment) in one transaction; returns rows deleted
        per table.

        Only for data that can be made again exactly -- ``study simulate --resume`` uses it to
        redo a simulated participant whose run was killed, so the resumed store matches an
        uninterrupted one. Raises ``SessionLockedError`` while a live process holds the
        participant's session, and ``UnknownParticipantError`` if they are not enrolled."""
        with self.transaction() as tx:
            tx.require_participant(participant)
            _require_no_live_holder(tx, participant, stale_after_s=stale_after_s)
            deleted = {
                "samples": tx.cur.execute(
                    "DELETE FROM samples WHERE trial_id IN "
                    "(SELECT trial_id FROM trials WHERE participant = ?)",
                    (participant,),
                ).rowcount
            }
            for table in (
                "ratings", "answers", "events", "trials", "leases", "assignments", "sessions",
                "demographics", "participants",
            ):  # fmt: skip
                deleted[table] = tx.cur.execute(
                    f"DELETE FROM {table} WHERE participant = ?", (participant,)
                ).rowcount
        return deleted

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


# ---- helpers ------------------------------------------------------------------------------------
def _require_no_live_holder(
    tx: Transaction, participant: str, *, stale_after_s: float
) -> dict[str, Any] | None:
    """Raise ``SessionLockedError`` while a live process (or this one) holds ``participant``'s
    lease; returns the dead holder's ``{pid, host, acquired_at}``, or ``None`` if no lease."""
    row = tx.cur.execute(
        "SELECT token, pid, host, process_start, acquired_at, heartbeat_at FROM leases "
        "WHERE participant = ?",
        (participant,),
    ).fetchone()
    if row is None:
        return None
    pid = os.getpid()
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
    return {"pid": holder_pid, "host": host, "acquired_at": acquired_at}


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

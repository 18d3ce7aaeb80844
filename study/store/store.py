"""``Store``: the study's SQLite database (WAL, versioned schema, one file per study).

Writes go through ``with store.transaction() as tx`` (``study.store.transaction``); opening,
schema checks and upgrades are in ``study.store.opening``, the readers in ``study.store.readers``
and the session leases in ``study.store.lease`` (mixed into ``Store``).

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

import os
import sqlite3
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from study.store import faults, opening
from study.store.errors import (
    NotAStoreError,
    ReadOnlyStoreError,
    StoreError,
    StoreNotWritableError,
    StoreWriteError,
)
from study.store.lease import Leases
from study.store.readers import Readers
from study.store.records import (
    StoreMeta,
)
from study.store.schema import SAMPLE_COLUMNS
from study.store.transaction import Transaction

_INSERT_SAMPLE = (
    f"INSERT INTO samples ({', '.join(SAMPLE_COLUMNS)}) "
    f"VALUES ({', '.join('?' for _ in SAMPLE_COLUMNS)})"
)


class Store(Leases, Readers):
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

"""Opening a store file: connect, read and check its schema version and protocol, create the
schema in an empty file, upgrade an older schema (and add the sample columns it lacks), keep the
protocol's text.

Nothing here writes to a file whose version or protocol is refused.
"""

from __future__ import annotations

import dataclasses
import sqlite3
import tomllib
from pathlib import Path

from study.store import faults
from study.store.errors import (
    NotAStoreError,
    ProtocolMismatchError,
    SchemaVersionError,
    StoreDamagedError,
    StoreError,
)
from study.store.records import StoreMeta
from study.store.schema import (
    ADDED_SAMPLE_TYPES,
    DDL,
    MIGRATIONS,
    READABLE_VERSIONS,
    SAMPLE_COLUMNS,
    SCHEMA_VERSION,
)
from study.store.values import now_iso


def connect(
    path: Path, *, readonly: bool, busy_timeout_s: float, immutable: bool = False
) -> sqlite3.Connection:
    """A connection to ``path``; ``immutable`` (read-only only) tells SQLite nobody writes the
    file, so it needs no journal files beside it (a store in a read-only folder)."""
    uri = f"file:{path.resolve()}?mode={'ro' if readonly else 'rwc'}"
    if immutable:
        uri += "&immutable=1"
    try:
        conn = sqlite3.connect(
            uri, uri=True, isolation_level=None, check_same_thread=False, timeout=busy_timeout_s
        )
    except sqlite3.Error as exc:
        raise StoreError(f"cannot open store {path}: {exc}") from exc
    return conn


def read_meta(conn: sqlite3.Connection, path: Path) -> StoreMeta | None:
    """The file's ``schema_version`` row, ``None`` for an empty file; errors for anything else."""
    try:
        names = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    except sqlite3.DatabaseError as exc:
        # Only these codes mean the bytes are not a (sound) database; anything else (a folder
        # it may not write its journal into, a full disk) is about the file system, not the file.
        if faults.primary_code(exc) == faults.SQLITE_CORRUPT:
            raise StoreDamagedError(damaged_message(path, str(exc))) from None
        if faults.primary_code(exc) == faults.SQLITE_NOTADB:
            raise NotAStoreError(
                f"{path} is not a SQLite database ({exc}); check the store path"
            ) from exc
        raise faults.write_error(path, exc) from exc
    if not names:
        return None
    if "schema_version" not in names:
        raise NotAStoreError(
            f"{path} is a SQLite database but not a study store (no schema_version table); "
            "check the store path"
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


FULL_CHECK_BYTES = 256 * 2**20
"""Up to this size a store opened for writing gets SQLite's ``integrity_check`` (indexes
against their tables too); above it ``quick_check`` (every page, every record; about 0.3 s
for 40 MB here, linear in the size)."""


def damaged_message(path: Path, problems: str) -> str:
    return (
        f"store {path} is damaged ({problems}); nothing was written to it. Keep a copy of the"
        f" file, copy what is readable into a new store with `python -m study salvage --db"
        f" {path} --out NEW.db`, and continue the study in NEW.db"
    )


def check_integrity(conn: sqlite3.Connection, path: Path) -> None:
    """Raise :class:`StoreDamagedError` unless SQLite finds the file sound (see
    ``FULL_CHECK_BYTES``); reads only."""
    pragma = "integrity_check" if path.stat().st_size <= FULL_CHECK_BYTES else "quick_check"
    try:
        rows = conn.execute(f"PRAGMA {pragma}(20)").fetchall()
    except sqlite3.DatabaseError as exc:
        if faults.primary_code(exc) in (faults.SQLITE_CORRUPT, faults.SQLITE_NOTADB):
            raise StoreDamagedError(damaged_message(path, str(exc))) from None
        raise faults.write_error(path, exc) from exc
    problems = [str(r[0]) for r in rows]
    if problems != ["ok"]:
        shown = "; ".join(problems[:3]) + (
            f"; {len(problems) - 3} more" if len(problems) > 3 else ""
        )
        raise StoreDamagedError(damaged_message(path, f"{pragma}: {shown}"))


def migrate(conn: sqlite3.Connection, meta: StoreMeta) -> StoreMeta:
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


def sample_columns(conn: sqlite3.Connection) -> frozenset[str]:
    """The columns the file's ``samples`` table has."""
    return frozenset(row[1] for row in conn.execute("PRAGMA table_info(samples)"))


def add_sample_columns(conn: sqlite3.Connection) -> tuple[str, ...]:
    """Add the declared sample columns (``app.trial.samples``) the file lacks, empty for the
    ticks already stored; returns their names. One transaction; another process may have
    added them meanwhile."""
    if sample_columns(conn) >= set(SAMPLE_COLUMNS):
        return ()
    conn.execute("BEGIN IMMEDIATE")
    try:
        have = sample_columns(conn)
        added = tuple(c for c in SAMPLE_COLUMNS if c not in have)
        for column in added:
            conn.execute(f"ALTER TABLE samples ADD COLUMN {column} {ADDED_SAMPLE_TYPES[column]}")
        conn.execute("COMMIT")
    except BaseException:
        if conn.in_transaction:
            conn.execute("ROLLBACK")
        raise
    return added


def stored_text(conn: sqlite3.Connection, content_hash: str) -> str | None:
    try:
        row = conn.execute(
            "SELECT text FROM protocols WHERE content_hash = ?", (content_hash,)
        ).fetchone()
    except sqlite3.OperationalError:  # a schema-1 file: no protocols table
        return None
    return None if row is None else str(row[0])


def record_protocol(conn: sqlite3.Connection, meta: StoreMeta, text: str) -> None:
    conn.execute(
        "INSERT OR IGNORE INTO protocols VALUES (?, ?, ?, ?, ?)",
        (meta.protocol_hash, meta.protocol_id, meta.protocol_version, text, now_iso()),
    )


def create_schema(
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
            meta = read_meta(conn, path)
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


def check_protocol(
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

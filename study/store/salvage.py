"""Copy what is readable of a damaged store into a new one (``python -m study salvage``).

A store that fails SQLite's check (``StoreDamagedError``) is never written to. What its pages
still hold can be read row by row: each table is read in key ranges, and a range that cannot
be read is halved until the unreadable keys are isolated (a damaged page costs the rows on it,
not the table). The new store gets the same schema and the damaged one's identity (protocol id,
content hash and version, creation time) and protocol texts, so sessions can go on in it; the
report counts, per table, the rows copied and the key ranges lost. Foreign keys are not
checked while copying (a trial whose session row was lost keeps its samples); the report names
such orphans so the experimenter can decide.

Samples have no rowid (their key is ``(trial_id, tick)``): they are read per trial, in tick
ranges.
"""

from __future__ import annotations

import shutil
import sqlite3
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from study.store.errors import StoreError
from study.store.schema import DDL, TABLES

MAX_TICK = 10**8
"""More ticks than any trial has (an hour at 1 kHz is 3.6e6)."""
MAX_FAILED_READS = 20_000
"""Reads that may fail per table while narrowing down damaged ranges; past it, the range left
is reported lost as a whole (a damaged interior page can hide millions of keys)."""


@dataclass
class TableSalvage:
    """What was copied of one table."""

    copied: int = 0
    lost_ranges: list[tuple[Any, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"copied": self.copied, "lost_ranges": [list(r) for r in self.lost_ranges[:20]]}


@dataclass
class SalvageReport:
    source: str
    target: str
    tables: dict[str, TableSalvage] = field(default_factory=dict)
    orphans: dict[str, int] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return not any(t.lost_ranges for t in self.tables.values())

    def as_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "target": self.target,
            "complete": self.complete,
            "tables": {name: t.as_dict() for name, t in self.tables.items()},
            "orphans": self.orphans,
        }


def salvage(source: str | Path, target: str | Path) -> SalvageReport:
    """Copy every readable row of the store at ``source`` into a new store at ``target`` (which
    must not exist); ``StoreError`` when nothing of it can be read (not even its identity)."""
    src_path, dst_path = Path(source), Path(target)
    if dst_path.exists():
        raise StoreError(f"{dst_path} exists; salvage writes a new store, name a new file")
    if not src_path.is_file():
        raise StoreError(f"no store at {src_path}")
    with tempfile.TemporaryDirectory(prefix="salvage-") as scratch:
        readable = _padded(src_path, Path(scratch))
        src = sqlite3.connect(f"file:{readable.resolve()}?mode=ro", uri=True, isolation_level=None)
        return _salvage(src, src_path, dst_path)


def _padded(path: Path, scratch: Path) -> Path:
    """``path``, or for a file cut short (shorter than its header says) a copy padded with
    zero pages in ``scratch``: SQLite refuses every read of a file shorter than its header's
    page count, while the pages that are there are still readable."""
    with path.open("rb") as f:
        header = f.read(100)
    if len(header) < 100 or not header.startswith(b"SQLite format 3\0"):
        return path
    page_size = int.from_bytes(header[16:18], "big") or 65536
    pages = int.from_bytes(header[28:32], "big")
    size = path.stat().st_size
    if pages * page_size <= size:
        return path
    copy = scratch / path.name
    shutil.copyfile(path, copy)
    with copy.open("r+b") as f:
        f.truncate(pages * page_size)
    return copy


def _salvage(src: sqlite3.Connection, src_path: Path, dst_path: Path) -> SalvageReport:
    try:
        try:
            identity = src.execute("SELECT * FROM schema_version").fetchall()
        except sqlite3.DatabaseError as exc:
            raise StoreError(
                f"{src_path}: not even the store's identity (schema_version) can be read ({exc});"
                " nothing to salvage"
            ) from None
        dst = sqlite3.connect(dst_path, isolation_level=None)
        try:
            dst.execute("PRAGMA journal_mode=WAL")
            dst.execute("BEGIN")
            for statement in DDL.split(";"):
                if statement.strip():
                    dst.execute(statement)
            report = SalvageReport(str(src_path), str(dst_path))
            for table in TABLES:
                report.tables[table] = _copy_table(src, dst, table, identity)
            dst.execute("COMMIT")
            report.orphans = _orphans(dst)
        except BaseException:
            dst.close()
            dst_path.unlink(missing_ok=True)
            raise
        dst.close()
    finally:
        src.close()
    return report


def _copy_table(
    src: sqlite3.Connection, dst: sqlite3.Connection, table: str, identity: list[tuple[Any, ...]]
) -> TableSalvage:
    done = TableSalvage()
    columns = _columns(dst, table)
    insert = f"INSERT OR IGNORE INTO {table} ({', '.join(columns)}) VALUES ({', '.join('?' * len(columns))})"
    select = ", ".join(columns)

    def copy(rows: list[tuple[Any, ...]]) -> None:
        try:
            dst.executemany(insert, rows)
            done.copied += len(rows)
        except sqlite3.Error:  # a garbled value breaks a constraint: row by row, skip those
            for row in rows:
                try:
                    dst.execute(insert, row)
                    done.copied += 1
                except sqlite3.Error:
                    done.lost_ranges.append((repr(row[:2]), "unreadable values"))

    budget = [MAX_FAILED_READS]

    if table == "schema_version":
        copy(identity)
    elif table == "samples":
        for trial_id in _trial_ids(src):
            _ranges(
                lambda lo, hi, t=trial_id: src.execute(
                    f"SELECT {select} FROM samples WHERE trial_id = ? AND tick BETWEEN ? AND ?",
                    (t, lo, hi),
                ).fetchall(),
                0,
                MAX_TICK,
                copy,
                lambda lo, hi, t=trial_id: done.lost_ranges.append(((t, lo), (t, hi))),
                budget,
            )
    else:
        have = _columns(src, table, missing_ok=True)
        if not have:
            return done
        shared = ", ".join(c if c in have else "NULL" for c in columns)
        _ranges(
            lambda lo, hi: src.execute(
                f"SELECT {shared} FROM {table} WHERE rowid BETWEEN ? AND ?", (lo, hi)
            ).fetchall(),
            0,
            _max_rowid(src, table),
            copy,
            lambda lo, hi: done.lost_ranges.append((lo, hi)),
            budget,
        )
    return done


def _max_rowid(src: sqlite3.Connection, table: str) -> int:
    """The table's largest rowid (the b-tree's rightmost path), or a bound on it."""
    try:
        row = src.execute(f"SELECT max(rowid) FROM {table}").fetchone()
    except sqlite3.DatabaseError:
        return 2**40
    return int(row[0] or 0)


def _ranges(
    read: Callable[[int, int], list[tuple[Any, ...]]],
    lo: int,
    hi: int,
    copy: Callable[[list[tuple[Any, ...]]], None],
    lost: Callable[[int, int], None],
    budget: list[int],
) -> None:
    """Read keys ``lo..hi``; a range that fails is halved until single keys fail (lost), or
    until ``budget[0]`` failed reads are spent (the range left is lost whole)."""
    stack = [(lo, hi)]
    while stack:
        a, b = stack.pop()
        try:
            rows = read(a, b)
        except sqlite3.DatabaseError:
            budget[0] -= 1
            if a == b or budget[0] <= 0:
                lost(a, b)
                continue
            mid = (a + b) // 2
            stack += [(mid + 1, b), (a, mid)]
            continue
        if rows:
            copy(rows)


def _trial_ids(src: sqlite3.Connection) -> Iterator[int]:
    """Every trial id with samples: those the trials table still names, plus a scan of the
    samples' own keys (a trial row may be lost while its samples are not)."""
    ids: set[int] = set()
    _ranges(
        lambda lo, hi: src.execute(
            "SELECT trial_id FROM trials WHERE rowid BETWEEN ? AND ?", (lo, hi)
        ).fetchall(),
        0,
        _max_rowid(src, "trials"),
        lambda rows: ids.update(int(r[0]) for r in rows),
        lambda lo, hi: None,
        [MAX_FAILED_READS],
    )
    last = 0
    while True:  # distinct trial ids of the samples, skipping past unreadable spots
        try:
            row = src.execute(
                "SELECT trial_id FROM samples WHERE trial_id > ? ORDER BY trial_id LIMIT 1", (last,)
            ).fetchone()
        except sqlite3.DatabaseError:
            last += 1
            if last > max(ids, default=0) + 1000:
                break
            continue
        if row is None:
            break
        last = int(row[0])
        ids.add(last)
    yield from sorted(ids)


def _columns(conn: sqlite3.Connection, table: str, *, missing_ok: bool = False) -> list[str]:
    try:
        return [r[1] for r in conn.execute(f"PRAGMA table_info({table})")]
    except sqlite3.DatabaseError:
        if missing_ok:
            return []
        raise


def _orphans(dst: sqlite3.Connection) -> dict[str, int]:
    """Rows whose parent row was lost (foreign keys the copy could not keep)."""
    found = {}
    for row in dst.execute("PRAGMA foreign_key_check"):
        found[row[0]] = found.get(row[0], 0) + 1
    return found

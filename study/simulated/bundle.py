"""One simulated participant's rows, made away from the study store and merged into it by one
writer.

Why: on a cluster the workers need not share a file system with the study store, and SQLite is
no database to write from many hosts at once. So a worker simulates its participant into a
private scratch store (the same session engine and store code as a live session), and ships the
whole file back as bytes (:class:`ParticipantBundle`; a few MB, compact and trivially
serialisable, where the same samples as Python tuples would be ten times larger). The client
process, the only writer of the study store, merges a bundle with :func:`merge_bundle` in ONE
transaction: a participant is either entirely in the store or not at all, whatever happens to
the client (Ctrl-C, a kill) or to the worker (lost mid-participant: nothing of it reached the
store, the scheduler simply runs it again).

Merging renumbers the scratch store's row ids (sessions, trials, ratings, answers, events) after the
study store's own, keeps every other value as the worker wrote it (wall-clock stamps included),
and leaves out the lease (the worker's process is gone).
"""

from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass
from typing import TYPE_CHECKING

from study.simulated.errors import SimulationRunError

if TYPE_CHECKING:
    from study.simulated.job import ParticipantResult
    from study.store import Store

_SRC = "bundle"
"""Schema name the bundle is attached under on the study store's connection."""


@dataclass(frozen=True)
class ParticipantBundle:
    """What a worker returns for one participant: how it went, and the scratch store's file."""

    result: ParticipantResult
    db: bytes


def read_bundle_file(path: str) -> bytes:
    """The bytes of a closed scratch store, taken out of WAL mode first: that folds the journal
    into the file, and SQLite cannot open a WAL-mode image in memory on the writer's side."""
    conn = sqlite3.connect(path, isolation_level=None)
    try:
        mode = conn.execute("PRAGMA journal_mode=DELETE").fetchone()[0]
        if mode != "delete":
            raise SimulationRunError(
                f"scratch store {path} stayed in journal mode {mode!r}; another process still "
                "has it open, which is a bug in the simulated-participant runner"
            )
        return conn.serialize()
    finally:
        conn.close()


def merge_bundle(store: Store, bundle: ParticipantBundle) -> None:
    """Write the bundle's participant into ``store`` in one transaction (all rows or none).

    Raises ``StoreError`` if the participant is already there (the participants table's key:
    a bundle is never written twice) and ``StoreWriteError`` on a full or read-only disk; either
    way nothing of the bundle is left in the store."""
    conn = store.conn
    # the store's connection takes URIs, where a bare ':memory:' would name a file
    conn.execute(f"ATTACH DATABASE 'file:{_SRC}?mode=memory' AS {_SRC}")
    try:
        conn.deserialize(bundle.db, name=_SRC)
        with store.transaction() as tx:
            _copy(tx.cur)
    finally:
        conn.execute(f"DETACH DATABASE {_SRC}")


def _columns(cur: sqlite3.Cursor, table: str) -> list[str]:
    return [row[1] for row in cur.execute(f"PRAGMA main.table_info({table})")]


def _copy(cur: sqlite3.Cursor) -> None:
    session_base = cur.execute("SELECT coalesce(max(session_id), 0) FROM main.sessions").fetchone()[
        0
    ]
    trial_base = cur.execute("SELECT coalesce(max(trial_id), 0) FROM main.trials").fetchone()[0]
    for table in ("participants", "demographics", "assignments"):
        cols = ", ".join(_columns(cur, table))
        cur.execute(f"INSERT INTO main.{table} ({cols}) SELECT {cols} FROM {_SRC}.{table}")

    def shifted(table: str, *, drop: str | None = None) -> tuple[str, str]:
        cols = [c for c in _columns(cur, table) if c != drop]
        source = [
            f"session_id + {session_base}"
            if c == "session_id"
            else f"trial_id + {trial_base}"
            if c == "trial_id"
            else c
            for c in cols
        ]
        return ", ".join(cols), ", ".join(source)

    for table, order, drop in (
        ("sessions", "session_id", None),
        ("trials", "trial_id", None),
        ("samples", "trial_id, tick", None),
        ("ratings", "rating_id", "rating_id"),
        ("answers", "answer_id", "answer_id"),
    ):
        cols, source = shifted(table, drop=drop)
        cur.execute(
            f"INSERT INTO main.{table} ({cols}) SELECT {source} FROM {_SRC}.{table} ORDER BY {order}"
        )
    # events: only the participant's own; a detail naming a trial names it by its new id
    rows = cur.execute(
        f"SELECT session_id, participant, at, kind, detail FROM {_SRC}.events "
        "WHERE participant IS NOT NULL OR session_id IS NOT NULL ORDER BY event_id"
    ).fetchall()
    for session_id, participant, at, kind, detail in rows:
        data = json.loads(detail)
        if isinstance(data, dict) and isinstance(data.get("trial_id"), int):
            data["trial_id"] += trial_base
            detail = json.dumps(data, sort_keys=True)
        cur.execute(
            "INSERT INTO main.events (session_id, participant, at, kind, detail) "
            "VALUES (?, ?, ?, ?, ?)",
            (
                None if session_id is None else session_id + session_base,
                participant,
                at,
                kind,
                detail,
            ),
        )

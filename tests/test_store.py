"""The SQLite store: schema and protocol checks, enrolment, leases, samples, read-back."""

from __future__ import annotations

import dataclasses
import sqlite3
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from study.session.sample_writer import MAX_FLUSH_INTERVAL_S, SampleWriter, sample_row
from study.store import (
    SAMPLE_COLUMNS,
    DuplicateParticipantError,
    InvalidParticipantIdError,
    NotAStoreError,
    ProtocolMismatchError,
    ReadOnlyStoreError,
    SampleFormatError,
    SchemaVersionError,
    SessionLockedError,
    Store,
    StoreError,
    UnknownParticipantError,
)
from tests.support.stores import HASH, enrol, new_trial, open_store, tick

ROOT = Path(__file__).resolve().parents[1]


def test_create_reopen_and_read_back(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    with open_store(db) as store:
        sid = enrol(store)
        assert store.meta.protocol_hash == HASH
        assert store.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    with open_store(db) as store:
        assert [p.participant for p in store.participants()] == ["P01"]
        assert store.session("P01").session_id == sid
        assert store.session("P01").status == "enrolled"
        assert [a.mode for a in store.assignments("P01")] == ["timid", "aggr"]
        # demographics live in their own table, not in participants or trials
        assert store.demographics("P01") == {"age": 31, "gender": "f"}
        cols = {r[1] for r in store.conn.execute("PRAGMA table_info(participants)")}
        assert "age" not in cols and "data" not in cols


def test_other_schema_version_or_protocol_is_refused_untouched(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    open_store(db).close()
    with pytest.raises(ProtocolMismatchError, match="written by protocol 'demo'"):
        Store.open(db, protocol_id="demo", protocol_hash="0" * 64)
    with pytest.raises(ProtocolMismatchError):
        Store.open(db, protocol_id="other", protocol_hash=HASH)
    conn = sqlite3.connect(db)
    conn.execute("UPDATE schema_version SET version = 99")
    conn.commit()
    conn.close()
    before = db.read_bytes()
    with pytest.raises(SchemaVersionError, match="version 99"):
        open_store(db)
    with pytest.raises(SchemaVersionError):
        Store.open_readonly(db)
    assert db.read_bytes() == before


def test_not_a_store(tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"hello, not sqlite" * 100)
    with pytest.raises(NotAStoreError, match="not a SQLite database"):
        open_store(junk)
    other = tmp_path / "other.db"
    conn = sqlite3.connect(other)
    conn.execute("CREATE TABLE x (a)")
    conn.commit()
    conn.close()
    with pytest.raises(NotAStoreError, match="no schema_version"):
        open_store(other)
    with pytest.raises(StoreError, match="does not exist"):
        open_store(tmp_path / "missing" / "s.db")


def test_participant_ids(tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        enrol(store)
        with pytest.raises(DuplicateParticipantError, match="P01 is already enrolled"):
            enrol(store)
        for bad in ("", "jane.doe@example.org", "Jane Doe", "x" * 40):
            with pytest.raises(InvalidParticipantIdError, match="pseudonym"):
                enrol(store, bad)
        with pytest.raises(UnknownParticipantError, match="P02 is not enrolled"):
            store.session("P02")
        with pytest.raises(UnknownParticipantError):
            store.acquire_lease("P02")
        assert len(store.participants()) == 1  # failed enrolments rolled back


def test_readonly_store_refuses_writes(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    with open_store(db) as store:
        enrol(store)
    with Store.open_readonly(db) as ro:
        assert ro.session("P01").participant == "P01"
        with pytest.raises(ReadOnlyStoreError):
            enrol(ro, "P02")


def test_lease_same_process_and_release(tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        enrol(store)
        lease = store.acquire_lease("P01")
        with pytest.raises(SessionLockedError, match="already open in this process"):
            store.acquire_lease("P01")
        store.heartbeat(lease)
        store.release_lease(lease)
        again = store.acquire_lease("P01")
        assert again.took_over is None
        with pytest.raises(SessionLockedError, match="taken over"):
            store.heartbeat(lease)


HOLDER = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {root!r})
    from study.store import Store
    store = Store.open({db!r}, protocol_id="demo", protocol_hash={h!r}, protocol_version="1")
    store.acquire_lease("P01")
    print("held", flush=True)
    time.sleep(60)
    """
)


def test_lease_held_by_live_process_then_taken_over_when_dead(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    with open_store(db) as store:
        enrol(store)
    code = HOLDER.format(root=str(ROOT), db=str(db), h=HASH)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        with open_store(db) as store:
            with pytest.raises(SessionLockedError, match=f"process {proc.pid}"):
                store.acquire_lease("P01")
            proc.kill()
            proc.wait()
            lease = store.acquire_lease("P01")
            assert lease.took_over is not None and lease.took_over["pid"] == proc.pid
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_samples_round_trip(tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        sid = enrol(store)
        tid = new_trial(store, sid)
        store.insert_samples([sample_row(tid, i, tick(i)) for i in range(5)])
        df = store.samples(tid)
        assert list(df.columns) == list(SAMPLE_COLUMNS)
        assert df["tick"].tolist() == [0, 1, 2, 3, 4]
        assert df.loc[2, "q7"] == pytest.approx(8.0)
        assert df.loc[2, "cmd1"] == pytest.approx(2.3)
        assert df.loc[3, "events"] == '["grasp_requested"]'
        assert df.loc[0, "probabilities"] == "[0.2, 0.8]"
        assert store.sample_count(tid) == 5
        with pytest.raises(StoreError, match=r"UNIQUE constraint failed.*nothing of this write"):
            store.insert_samples([sample_row(tid, 5, tick(5)), sample_row(tid, 4, tick(4))])
        assert store.sample_count(tid) == 5  # the whole batch rolled back
        bad = dataclasses.replace(tick(0), q=np.zeros(6))
        with pytest.raises(SampleFormatError, match="'q' has 6 values, expected 7"):
            sample_row(tid, 9, bad)


def test_sample_writer_batches_within_250ms_and_flushes(tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        sid = enrol(store)
        tid = new_trial(store, sid)
        with pytest.raises(StoreError, match="flush_interval_s"):
            SampleWriter(store, flush_interval_s=MAX_FLUSH_INTERVAL_S + 0.01)
        writer = SampleWriter(store, flush_interval_s=0.05)
        for i in range(10):
            writer.add(tid, i, tick(i))
        deadline = time.monotonic() + 2.0
        while store.sample_count(tid) < 10 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert store.sample_count(tid) == 10  # committed by the thread without flush()
        for i in range(10, 20):
            writer.add(tid, i, tick(i))
        writer.flush()
        assert store.sample_count(tid) == 20
        writer.close()
        assert writer.stats.rows == 20


def test_sample_writer_keeps_rows_when_a_commit_fails(tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        sid = enrol(store)
        tid = new_trial(store, sid)
        writer = SampleWriter(store, flush_interval_s=0.25)
        writer.add(tid, 0, tick(0))
        writer.add(tid, 0, tick(0))  # duplicate (trial_id, tick): the batch is refused
        with pytest.raises(StoreError, match="could not commit 2 samples"):
            writer.flush()
        assert writer.pending == 2 and store.sample_count(tid) == 0
        with pytest.raises(StoreError, match="not reaching the store"):
            writer.add(tid, 1, tick(1))
        assert writer.pending == 3  # the new row is kept too, for the next commit
        with pytest.raises(StoreError, match="could not commit"):
            writer.close()  # the thread stops; the rows are still reported, not dropped


def test_sessions_of_one_store_share_one_commit_and_a_bad_batch_holds_back_only_its_own(
    tmp_path: Path,
) -> None:
    """Eight live sessions each committing their own batches queued for the file's write lock
    (batches up to 0.76 s apart); their writers now share one committer thread per store, and a
    writer whose rows are refused (a duplicate tick) does not stop the others' samples."""
    with open_store(tmp_path / "s.db") as store:
        trials = [new_trial(store, enrol(store, f"P0{n}")) for n in (1, 2, 3)]

        def running() -> set[threading.Thread]:
            return {t for t in threading.enumerate() if t.name == "sample-committer"}

        before = running()  # other tests' stores in this process may have theirs
        writers = [SampleWriter(store, flush_interval_s=0.05) for _ in trials]
        committers = running() - before
        assert len(committers) == 1
        bad = writers[0]
        bad.add(trials[0], 0, tick(0))
        bad.add(trials[0], 0, tick(0))  # refused by the store
        for i in range(20):
            for writer, tid in zip(writers[1:], trials[1:], strict=True):
                writer.add(tid, i, tick(i))
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and any(store.sample_count(t) < 20 for t in trials[1:]):
            time.sleep(0.01)
        assert [store.sample_count(t) for t in trials] == [0, 20, 20]
        assert isinstance(bad.error, StoreError) and bad.pending == 2
        assert all(w.error is None and w.stats.rows == 20 for w in writers[1:])
        for writer in writers[1:]:
            writer.close()
        with pytest.raises(StoreError, match="could not commit"):
            bad.close()  # the last writer: the committer's thread ends, the rows are reported
        assert not any(t is c and t.is_alive() for t in threading.enumerate() for c in committers)

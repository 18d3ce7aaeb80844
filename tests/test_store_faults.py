"""A store on a disk that is full or read-only: typed errors that say so, nothing committed lost.

Read-only folders and files are real: the tests run as an unprivileged user for the duration of
the open (as root, whose writes no permission bit stops, they switch the effective user to
``nobody`` and back), so SQLite, the probes and the kernel's permission checks are the ones a
lab's machine would use. A full disk is SQLite's own ``SQLITE_FULL``, made by capping the
connections' ``max_page_count`` (``tests.disk_full``) -- the same error code and path as a full
file system.
"""

from __future__ import annotations

import os
import shutil
import sqlite3
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from study.session.sample_writer import SampleWriter, sample_row
from study.store import (
    NotAStoreError,
    Store,
    StoreError,
    StoreFullError,
    StoreNotWritableError,
    StoreWriteError,
)
from tests.disk_full import cap, uncap
from tests.support.stores import enrol, new_trial, open_store, tick

NOBODY = 65534


@contextmanager
def unprivileged() -> Iterator[None]:
    """Run the block without root's power to ignore permission bits (a no-op for a normal
    user). Only the effective user changes, so root is restored afterwards."""
    if os.geteuid() != 0:
        yield
        return
    os.seteuid(NOBODY)
    try:
        assert os.geteuid() == NOBODY
        yield
    finally:
        os.seteuid(0)


@pytest.fixture
def shared_dir() -> Iterator[Path]:
    """A folder the unprivileged user can reach (pytest's tmp_path is private to root)."""
    path = Path(tempfile.mkdtemp(prefix="store-faults-"))
    path.chmod(0o755)
    yield path / "folder"
    for p in [path, *path.rglob("*")]:
        p.chmod(0o777)
    shutil.rmtree(path)


def make_store(folder: Path) -> Path:
    folder.mkdir(mode=0o777)
    folder.chmod(0o777)
    db = folder / "study.db"
    with open_store(db) as store:
        enrol(store)
    for p in folder.iterdir():
        p.chmod(0o666)
    return db


# ---- read-only ----------------------------------------------------------------------------------
def test_valid_store_in_read_only_folder_says_so(shared_dir: Path) -> None:
    db = make_store(shared_dir)
    shared_dir.chmod(0o555)  # the file itself stays writable
    with unprivileged(), pytest.raises(StoreNotWritableError) as exc:
        open_store(db)
    message = str(exc.value)
    assert f"the folder {shared_dir} is not writable (permission denied)" in message
    assert "Move the store to a writable folder" in message
    assert "not a SQLite database" not in message
    assert not isinstance(exc.value, NotAStoreError)
    assert exc.value.path == db


def test_read_only_store_file_says_so(shared_dir: Path) -> None:
    db = make_store(shared_dir)
    db.chmod(0o444)
    read_only = r"the store file .*study\.db is read-only"
    with unprivileged(), pytest.raises(StoreNotWritableError, match=read_only):
        open_store(db)


def test_store_in_read_only_folder_can_still_be_read(shared_dir: Path) -> None:
    """Export and analysis read an archived store in place; SQLite cannot create its journal
    index there, so the store is read as immutable (nobody can write in that folder)."""
    db = make_store(shared_dir)
    shared_dir.chmod(0o555)
    with unprivileged(), Store.open_readonly(db) as store:
        assert [p.participant for p in store.participants()] == ["P01"]
        assert store.integrity_check() == "ok"
    assert sorted(p.name for p in shared_dir.iterdir()) == ["study.db"]


def test_read_only_folder_with_unmerged_journal_is_refused_not_misread(shared_dir: Path) -> None:
    """A -wal holding commits would be ignored by an immutable read: refuse, say what to do."""
    shared_dir.mkdir(mode=0o777)
    db = shared_dir / "study.db"
    store = open_store(db)
    try:
        enrol(store)  # committed to the -wal, not yet checkpointed into the file
        copy = shared_dir / "copy"
        copy.mkdir()
        for suffix in ("", "-wal"):
            shutil.copy(f"{db}{suffix}", copy / f"study.db{suffix}")
    finally:
        store.close()
    assert (copy / "study.db-wal").stat().st_size > 0
    copy.chmod(0o555)
    refused = r"copy the folder .* somewhere writable"
    with unprivileged(), pytest.raises(StoreNotWritableError, match=refused):
        Store.open_readonly(copy / "study.db")


def test_a_damaged_file_is_still_reported_as_not_a_store(tmp_path: Path) -> None:
    db = tmp_path / "junk.db"
    db.write_bytes(b"this is not sqlite" * 500)
    with pytest.raises(NotAStoreError, match="is not a SQLite database"):
        open_store(db)


# ---- full disk ----------------------------------------------------------------------------------
def test_full_disk_is_a_typed_error_and_keeps_committed_data(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    with open_store(db) as store:
        trial = new_trial(store, enrol(store))
        store.insert_samples([sample_row(trial, i, tick(i)) for i in range(10)])
        cap(store, extra_pages=2)
        with pytest.raises(StoreFullError) as exc:
            store.insert_samples([sample_row(trial, i, tick(i)) for i in range(10, 2000)])
        assert isinstance(exc.value, StoreWriteError) and isinstance(exc.value, StoreError)
        message = str(exc.value)
        assert f"store {db}: the disk is full" in message
        assert "nothing of this write was kept" in message
        assert f"Free space on the disk holding {tmp_path}" in message
        assert store.sample_count(trial) == 10
        assert store.integrity_check() == "ok"


def test_sample_writer_keeps_the_type_and_writes_held_rows_once_space_is_freed(
    tmp_path: Path,
) -> None:
    with open_store(tmp_path / "s.db") as store:
        trial = new_trial(store, enrol(store))
        writer = SampleWriter(store, flush_interval_s=0.25)
        try:
            cap(store, extra_pages=1)
            for i in range(400):
                writer.add_row(sample_row(trial, i, tick(i)))
            with pytest.raises(StoreFullError, match="could not commit 400 samples"):
                writer.flush()
            with pytest.raises(StoreFullError, match="401 rows are held in memory") as exc:
                writer.add_row(sample_row(trial, 400, tick(400)))
            assert "the disk is full" in str(exc.value)
            assert isinstance(writer.error, StoreFullError)
            uncap(store)  # space freed
            assert writer.flush() == 401
            assert writer.error is None
            writer.add_row(sample_row(trial, 401, tick(401)))  # no error pending any more
        finally:
            writer.close()
        assert store.sample_count(trial) == 402


def test_write_error_codes_map_to_types(tmp_path: Path) -> None:
    from study.store.faults import write_error

    path = tmp_path / "s.db"

    def error(code: int, text: str) -> sqlite3.Error:
        exc = sqlite3.OperationalError(text)
        exc.sqlite_errorcode = code  # type: ignore[attr-defined]
        return exc

    assert type(write_error(path, error(13, "database or disk is full"))) is StoreFullError
    ro = write_error(path, error(8, "attempt to write a readonly database"))
    assert type(ro) is StoreNotWritableError
    io = write_error(path, error(10 | (3 << 8), "disk I/O error"))
    assert type(io) is StoreWriteError and "the disk refused a write" in str(io)
    other = write_error(path, error(19, "UNIQUE constraint failed"))
    assert type(other) is StoreError

"""A damaged store is refused before anything is written, and what is readable can be saved.

The attack pass wrote 64 KiB of garbage into the middle of a store: nothing noticed on open,
``run`` wrote a whole session into it, ``serve`` enrolled, ``simulate --resume`` reported
success and only ``export`` failed, with a traceback. Each kind of damage tried here is now a
``StoreDamagedError`` on open (the file's bytes unchanged) whose message names
``python -m study salvage``, and salvage copies every row it can still read into a new store
that opens cleanly.
"""

from __future__ import annotations

import hashlib
import json
import os
import sqlite3
from pathlib import Path

import pytest

from study.__main__ import main as study_main
from study.session.sample_writer import sample_row
from study.store import NotAStoreError, Store, StoreDamagedError
from study.store.salvage import salvage
from tests.support.cli import Ran, run_main
from tests.support.stores import enrol, new_trial, open_store, tick

PAGE = 4096
TICKS = 1500


@pytest.fixture
def store_file(tmp_path: Path) -> Path:
    """A closed store of one participant with three trials of 1,500 samples (about 2 MB)."""
    path = tmp_path / "study.db"
    store = open_store(path)
    session = enrol(store)
    for step in (1, 2, 3):
        trial = new_trial(store, session, step=step)
        store.insert_samples([sample_row(trial, i, tick(i)) for i in range(TICKS)])
    store.close()
    with sqlite3.connect(path) as conn:  # fold the journal into the file, as a closed store is
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    return path


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def garbage_in_the_middle(path: Path) -> None:
    size = path.stat().st_size
    with path.open("r+b") as f:
        f.seek((size // 2) // PAGE * PAGE + 123)
        f.write(os.urandom(64 * 1024))


def truncated(path: Path) -> None:
    with path.open("r+b") as f:
        f.truncate(path.stat().st_size * 6 // 10 // PAGE * PAGE)


def zeroed_page(path: Path) -> None:
    pages = path.stat().st_size // PAGE
    with path.open("r+b") as f:
        f.seek(pages * 3 // 4 * PAGE)
        f.write(b"\0" * PAGE)


def index_page_scrambled(path: Path) -> None:
    """A page of the trials index overwritten: its table is intact, the index is not (only
    integrity_check, not quick_check, compares the two)."""
    with sqlite3.connect(path) as conn:
        root = conn.execute(
            "SELECT rootpage FROM sqlite_master WHERE name = 'trials_by_session'"
        ).fetchone()[0]
    with path.open("r+b") as f:
        f.seek((root - 1) * PAGE + 8)
        f.write(bytes(range(256)) * 4)


DAMAGE = {
    "64 KiB of garbage in the middle": garbage_in_the_middle,
    "cut short": truncated,
    "a zeroed page": zeroed_page,
    "an index page scrambled": index_page_scrambled,
}


@pytest.mark.parametrize("damage", DAMAGE)
def test_a_damaged_store_is_refused_untouched_and_says_how_to_recover(
    store_file: Path, damage: str
) -> None:
    DAMAGE[damage](store_file)
    before = digest(store_file)
    with pytest.raises(StoreDamagedError) as info:
        open_store(store_file)
    assert "is damaged" in str(info.value)
    assert f"python -m study salvage --db {store_file}" in str(info.value)
    with pytest.raises(StoreDamagedError):
        Store.open_readonly(store_file, verify=True)
    assert digest(store_file) == before  # nothing written, not even a journal replay
    assert not Path(f"{store_file}-wal").exists() or Path(f"{store_file}-wal").stat().st_size == 0


@pytest.mark.parametrize("damage", DAMAGE)
def test_salvage_copies_what_is_readable_into_a_store_that_opens(
    store_file: Path, tmp_path: Path, damage: str
) -> None:
    DAMAGE[damage](store_file)
    out = tmp_path / "salvaged.db"
    report = salvage(store_file, out)
    copied = report.tables["samples"].copied
    assert report.tables["schema_version"].copied == 1
    assert report.tables["participants"].copied == 1
    assert 0 < copied <= 3 * TICKS
    with open_store(out) as store:  # same identity, sound: sessions can go on in it
        assert store.meta.protocol_id == "demo"
        assert store.sample_count(1) + store.sample_count(2) + store.sample_count(3) == copied
    if damage == "an index page scrambled":  # the rows were all there
        assert copied == 3 * TICKS and report.complete


def test_a_store_whose_header_is_garbage_is_not_called_a_store(store_file: Path) -> None:
    with store_file.open("r+b") as f:
        f.write(os.urandom(100))
    with pytest.raises(NotAStoreError, match="not a SQLite database"):
        open_store(store_file)


def test_commands_refuse_a_damaged_store_in_one_line(
    tmp_path: Path, short_protocol: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``run`` writes a session; after 64 KiB of garbage, ``run``, ``simulate --resume`` and
    ``export`` stop at once with the salvage hint (exit 2, no traceback); salvage then gives a
    store that ``export`` reads. Each command is ``python -m study``'s ``main`` in this process
    (all that the module does besides ``sys.exit``): an exception it let through would fail
    the test as a traceback would, without five interpreters' start-up and imports."""
    db = tmp_path / "study.db"

    def study(*argv: str) -> Ran:
        return run_main(study_main, argv, capsys)

    done = study("run", "--protocol", str(short_protocol), "--db", str(db), "--participant", "P01")
    assert done.returncode == 0, done.stderr
    with sqlite3.connect(db) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    garbage_in_the_middle(db)
    before = digest(db)
    for argv in (
        ["run", "--protocol", str(short_protocol), "--db", str(db), "--participant", "P02"],
        [
            "simulate",
            "--protocol",
            str(short_protocol),
            "--db",
            str(db),
            "--participants",
            "1",
            "--resume",
            "--no-progress",
        ],
        ["export", "--db", str(db), "--out", str(tmp_path / "export")],
    ):
        done = study(*argv)
        assert done.returncode == 2, (argv, done.stderr)
        assert "Traceback" not in done.stderr and "study salvage" in done.stderr, done.stderr
    assert digest(db) == before
    out = tmp_path / "salvaged.db"
    done = study("salvage", "--db", str(db), "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["tables"]["trials"]["copied"] >= 1
    done = study("export", "--db", str(out), "--out", str(tmp_path / "e"))
    assert done.returncode == 0, done.stderr

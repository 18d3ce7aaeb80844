"""A reference simulated run and what a store holds, for the resume and Dask tests (a resumed or
distributed run must store what an uninterrupted local run stores)."""

from __future__ import annotations

import hashlib
import os
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from study.simulated import simulate
from study.store import Store
from tests.protocol_copies import short_protocol

try:
    import fcntl
except ImportError:  # not POSIX: each pytest-xdist worker builds its own copy
    fcntl = None  # type: ignore[assignment]


def reference_run(protocol: Path, folder: Path, *, participants: int, seed: int) -> Path:
    """An uninterrupted simulation in ``folder``: the data every other run must reproduce."""
    db = folder / "sim.db"
    report = simulate(
        protocol_path=protocol, db=db, participants=participants, seed=seed, progress=False
    )
    assert report.errors == [] and report.error is None
    return db


def shared_reference(
    tmp_path_factory: pytest.TempPathFactory, *, participants: int, seed: int
) -> tuple[Path, Path]:
    """(protocol, reference store): the paper's protocol with 20 s trials and one training run,
    and :func:`reference_run` of it, built once per test run -- the pytest-xdist workers share
    one copy (a file lock in the run's temporary folder), so the resume and Dask modules, each
    on its own worker, simulate the reference once between them. Read it; never write to it."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the run's folder, above every worker's own
    folder = root / f"simulated-reference-p{participants}-s{seed}"
    folder.mkdir(exist_ok=True)
    db, done = folder / "sim.db", folder / "done"
    with _locked(folder / "lock"):
        if not done.exists():
            for stale in folder.glob("sim.db*"):  # a worker that failed half-way
                stale.unlink()
            protocol = short_protocol(folder, training_runs=1)
            reference_run(protocol, folder, participants=participants, seed=seed)
            done.touch()
    return folder / "short.toml", db


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    with path.open("a") as handle:
        if fcntl is not None:
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            if fcntl is not None:
                fcntl.flock(handle, fcntl.LOCK_UN)


def content(db: Path) -> dict[str, Any]:
    """Everything a run writes, keyed by participant and step, without timestamps and ids."""
    with Store.open_readonly(db) as store:
        assert store.integrity_check() == "ok"
        key = {t.trial_id: (t.participant, t.step, t.attempt) for t in store.trials()}
        samples = store.samples()
        digests = {}
        for trial_id, rows in samples.groupby("trial_id"):
            values = rows.drop(columns=["trial_id"]).to_csv(index=False)
            digests[key[int(trial_id)]] = hashlib.sha256(values.encode()).hexdigest()
        return {
            "participants": [(p.participant, p.schedule_row) for p in store.participants()],
            "demographics": {
                p.participant: store.demographics(p.participant) for p in store.participants()
            },
            "sessions": sorted(
                (s.participant, s.status, s.cursor, s.seed) for s in store.sessions()
            ),
            "trials": sorted(
                (
                    t.participant,
                    t.step,
                    t.attempt,
                    t.task,
                    t.mode,
                    t.run,
                    t.seed,
                    t.status,
                    t.outcome,
                    t.success,
                    t.duration_s,
                    t.ticks,
                    t.target,
                )
                for t in store.trials()
            ),
            "samples": digests,
            "ratings": sorted(
                (r.participant, r.step, r.item, r.value, key.get(r.trial_id))
                for r in store.ratings()
            ),
            "events": sorted(
                (e.participant or "", e.kind) for e in store.events() if e.kind != "close"
            ),
        }


def progress(db: Path) -> tuple[int, int]:
    """(trial rows, completed sessions) as another process sees the file; (0, 0) before it
    has a schema."""
    try:
        conn = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)
        try:
            trials = conn.execute("SELECT count(*) FROM trials").fetchone()[0]
            done = conn.execute(
                "SELECT count(*) FROM sessions WHERE status = 'completed'"
            ).fetchone()[0]
        finally:
            conn.close()
    except sqlite3.Error:
        return 0, 0
    return int(trials), int(done)

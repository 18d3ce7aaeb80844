"""Simulating with worker processes writes the same data as one process (same store, WAL).

Two participants through the real engine, once in-process and once with two spawned workers
sharing one SQLite store; trials, samples and answers must match participant by participant.
The protocol is the study's own with a 20 s time limit to keep the test short.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from study.simulated import simulate
from study.store import Store

pytestmark = pytest.mark.slow


def content(db: Path) -> tuple[list[tuple], list[tuple], list[int]]:
    with Store.open_readonly(db) as store:
        trials = [
            (t.participant, t.step, t.attempt, t.task, t.mode, t.outcome, t.duration_s, t.ticks)
            for t in store.trials()
        ]
        ratings = sorted((r.participant, r.step, r.item, r.value) for r in store.ratings())
        samples = [store.sample_count(t.trial_id) for t in store.trials()]
    return sorted(trials, key=str), ratings, sorted(samples)


def test_two_workers_write_what_one_process_writes(tmp_path: Path, short_protocol: Path) -> None:
    one = simulate(
        protocol_path=short_protocol,
        db=tmp_path / "one.db",
        participants=2,
        seed=11,
        workers=1,
        progress=False,
    )
    two = simulate(
        protocol_path=short_protocol,
        db=tmp_path / "two.db",
        participants=2,
        seed=11,
        workers=2,
        progress=False,
    )
    assert one.errors == two.errors == []
    assert (one.trials, one.ratings) == (two.trials, two.ratings) == (22, 62)
    assert content(tmp_path / "one.db") == content(tmp_path / "two.db")
    with Store.open_readonly(tmp_path / "two.db") as store:
        assert store.integrity_check() == "ok"
        assert {s.status for s in store.sessions()} == {"completed"}

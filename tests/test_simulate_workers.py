"""Simulating with worker processes writes the same data as one process (same store, WAL).

Three participants through the real engine with two spawned workers sharing one SQLite store,
compared with the uninterrupted one-process run the resume and Dask tests compare with
(:func:`tests.support.simulated_runs.shared_reference`, built once per test run): participants,
seeds, trials, every sample value, ratings and event kinds must match. The protocol is the
study's own with a 20 s time limit and one training run to keep the test short.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from study.simulated import simulate
from study.store import Store
from tests.support.simulated_runs import content, shared_reference

pytestmark = pytest.mark.slow

PARTICIPANTS = 3
SEED = 7  # the resume and Dask tests' too (branch lead): one reference run serves all three


def same_data(db: Path) -> dict[str, Any]:
    """``content`` with participants sorted: they are listed by enrolment stamp, which depends on
    which worker started first."""
    data = content(db)
    data["participants"] = sorted(data["participants"])
    return data


def test_two_workers_write_what_one_process_writes(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    protocol, one = shared_reference(tmp_path_factory, participants=PARTICIPANTS, seed=SEED)
    two = simulate(
        protocol_path=protocol,
        db=tmp_path / "two.db",
        participants=PARTICIPANTS,
        seed=SEED,
        workers=2,
        progress=False,
    )
    assert two.errors == []
    with Store.open_readonly(one) as store:
        assert (two.trials, two.ratings) == (len(store.trials()), len(store.ratings()))
    assert two.trials == PARTICIPANTS * 9  # one training run and eight task trials each
    assert same_data(tmp_path / "two.db") == same_data(one)
    with Store.open_readonly(tmp_path / "two.db") as store:
        assert store.integrity_check() == "ok"
        assert {s.status for s in store.sessions()} == {"completed"}

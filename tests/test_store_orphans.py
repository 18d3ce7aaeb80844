"""A trial left ``running`` by a dead process reads back (and exports) as ``interrupted``;
while its process lives it stays ``running``; the file is never written by the readers."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from study.export import tidy_tables
from study.store import ORPHAN_NOTE, SAMPLE_COLUMNS, Store

ROOT = Path(__file__).resolve().parents[1]
HASH = hashlib.sha256(b"protocol").hexdigest()


def open_store(path: Path) -> Store:
    return Store.open(path, protocol_id="demo", protocol_hash=HASH, protocol_version="1")


def sample(trial_id: int, tick: int) -> list[object]:
    values: dict[str, object] = {c: 0.0 for c in SAMPLE_COLUMNS}
    values.update(
        trial_id=trial_id, tick=tick, t=0.01 * tick, predicted=0, probabilities="[1.0]", events="[]"
    )
    return [values[c] for c in SAMPLE_COLUMNS]


def running_trial(store: Store, participant: str = "P01", *, samples: int = 4) -> int:
    """Enrol ``participant`` and start a trial with ``samples`` ticks stored (no end)."""
    with store.transaction() as tx:
        sid = tx.enrol(participant, schedule_row=0, assignments=[], seed=1)
        tid = tx.insert_trial(
            session_id=sid,
            participant=participant,
            step=1,
            trial_number=1,
            phase="training",
            mode="none",
            attempt=1,
            seed=1,
            goal_names=["mug"],
            goal_positions=[[0.5, 0, 0]],
        )
    store.insert_samples([sample(tid, k) for k in range(samples)])
    return tid


def status(store: Store, trial_id: int) -> tuple[str, str | None, bool | None, int]:
    t = store.trial(trial_id)
    return t.status, t.outcome, t.success, t.ticks


def test_running_trial_without_a_live_lease_reads_as_interrupted(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    with open_store(db) as store:
        tid = running_trial(store)
        lease = store.acquire_lease("P01")  # this process: live
        assert status(store, tid) == ("running", None, None, 0)
        store.release_lease(lease)  # e.g. lease row gone, trial never ended
        assert status(store, tid) == ("interrupted", "interrupted", False, 4)
        assert store.trial(tid).duration_s == pytest.approx(0.03)
        assert store.trial(tid).note == ORPHAN_NOTE
        assert [t.status for t in store.trials()] == ["interrupted"]
        assert store.trial(tid, raw=True).status == "running"
        assert [t.status for t in store.trials(raw=True)] == ["running"]
        frame = store.frame("trials")
        assert frame.loc[0, "status"] == "interrupted" and frame.loc[0, "ticks"] == 4
        assert store.frame("trials", raw=True).loc[0, "status"] == "running"
    before = db.read_bytes()
    with Store.open_readonly(db) as store:
        assert store.orphaned_trials() == [tid]
        trials = tidy_tables(store, search=[])["trials"]
        assert (trials.loc[0, "status"], trials.loc[0, "outcome"]) == ("interrupted", "interrupted")
        assert trials.loc[0, "ticks"] == 4 and not trials.loc[0, "success"]
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "study", "export", "--db", str(db), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert f"trials [{tid}] were left running by a process that died" in proc.stderr
    assert json.loads((out / "metadata.json").read_text())["orphaned_trials"] == [tid]
    assert pd.read_csv(out / "trials.csv")["status"].tolist() == ["interrupted"]
    assert db.read_bytes() == before  # readers never write


def set_lease(store: Store, **fields: object) -> None:
    with store.transaction() as tx:
        for key, value in fields.items():
            tx.cur.execute(f"UPDATE leases SET {key} = ? WHERE participant = 'P01'", (value,))


def test_lease_holder_liveness_decides(tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        tid = running_trial(store)
        store.acquire_lease("P01")
        set_lease(store, process_start="1")  # our pid, but another process's start: recycled
        assert store.trial(tid).status == "interrupted"
        set_lease(store, host="lab-pc-2", heartbeat_at=time.time())  # another host, fresh beat
        assert store.trial(tid).status == "running"
        set_lease(store, heartbeat_at=time.time() - 60)  # another host, silent for a minute
        assert store.trial(tid).status == "interrupted"


HOLDER = textwrap.dedent(
    """
    import os, sys
    sys.path.insert(0, {root!r})
    from study.store import Store
    store = Store.open({db!r}, protocol_id="demo", protocol_hash={h!r}, protocol_version="1")
    store.acquire_lease("P01")
    print("held", flush=True)
    sys.stdin.readline()
    os._exit(0)  # dies holding the lease, its trial still running
    """
)


def test_trial_of_a_live_process_stays_running_until_it_dies(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    with open_store(db) as store:
        tid = running_trial(store)
    code = HOLDER.format(root=str(ROOT), db=str(db), h=HASH)
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        with Store.open_readonly(db) as store:
            assert status(store, tid) == ("running", None, None, 0)
            assert tidy_tables(store, search=[])["trials"].loc[0, "status"] == "running"
        proc.communicate("\n", timeout=30)
    finally:
        proc.kill()
    with Store.open_readonly(db) as store:
        assert status(store, tid) == ("interrupted", "interrupted", False, 4)
        assert len(store.frame("leases")) == 1  # the dead process's lease row is still there

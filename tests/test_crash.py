"""kill -9 a real ``python -m study run`` mid-trial, then resume: nothing completed is lost.

After every SIGKILL: ``PRAGMA integrity_check`` is ok; every trial and rating the store showed
as committed before the kill is still there; the trial that was running keeps its samples up to
the last batch (consecutive ticks from 0); until a resume, readers and export report it
``interrupted`` while its row still says ``running`` (nothing written); ``--resume`` marks it
interrupted and runs the same step again, so the session ends with the full schedule.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from study.export import tidy_tables
from study.store import ORPHAN_NOTE, Store

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ROOT / "protocols" / "dragan2013.toml"

pytestmark = pytest.mark.slow


def start(db: Path, *extra: str, realtime: bool = True) -> subprocess.Popen[str]:
    """``study run`` for P01; paced like a real session unless ``realtime`` is false (then the
    whole session takes about 3 s, too fast to kill mid-trial reliably)."""
    protocol = db.parent / "protocol.toml"  # a snapshot: the shared file may change meanwhile
    if not protocol.exists():
        protocol.write_text(PROTOCOL.read_text())
    cmd = [
        sys.executable,
        "-m",
        "study",
        "run",
        "--protocol",
        str(protocol),
        "--db",
        str(db),
        "--participant",
        "P01",
        "--input",
        "scripted",
        "--seed",
        "1",
        *(["--realtime"] if realtime else []),
        *extra,
    ]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}
    return subprocess.Popen(
        cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def snapshot(db: Path) -> dict[str, object]:
    """What the store holds now, read by another process's view (read-only connection)."""
    if not db.exists():
        return {"completed": set(), "ratings": set(), "running": None, "samples": 0}
    with Store.open_readonly(db) as store:
        trials = store.trials()
        running = [t for t in trials if t.status == "running"]
        return {
            "completed": {
                (t.trial_id, t.step, t.attempt) for t in trials if t.status == "completed"
            },
            "ratings": {(r.step, r.item, r.value) for r in store.ratings()},
            "running": running[0] if running else None,
            "samples": store.sample_count(running[0].trial_id) if running else 0,
        }


def wait_for(db: Path, proc: subprocess.Popen[str], predicate, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        try:
            snap = snapshot(db)
        except Exception:  # the file is being created
            snap = None
        if snap is not None and predicate(snap):
            return snap
        time.sleep(0.02)
    raise AssertionError("condition not reached before timeout")


def kill(proc: subprocess.Popen[str]) -> None:
    """SIGKILL ``proc``; a process that already exited by itself must have exited cleanly."""
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    assert proc.returncode in (-signal.SIGKILL, 0)


def session_status(db: Path) -> str:
    with Store.open_readonly(db) as store:
        return store.session("P01").status


def check_after_kill(db: Path, before: dict[str, object]) -> None:
    with Store.open_readonly(db) as store:
        assert store.integrity_check() == "ok"
        trials = store.trials()
        completed = {(t.trial_id, t.step, t.attempt) for t in trials if t.status == "completed"}
        assert before["completed"] <= completed  # type: ignore[operator]
        ratings = {(r.step, r.item, r.value) for r in store.ratings()}
        assert before["ratings"] <= ratings  # type: ignore[operator]
        assert not [t for t in trials if t.status == "running"]  # its process is dead
        for t in store.trials(raw=True):
            if t.status == "running":  # the interrupted trial, not yet marked (no resume yet)
                ticks = store.samples(t.trial_id)["tick"].tolist()
                assert ticks == list(range(len(ticks)))
                assert len(ticks) >= (before["samples"] if before["running"] else 0)  # type: ignore[operator]
                reported = store.trial(t.trial_id)
                assert (reported.status, reported.outcome, reported.success) == (
                    "interrupted",
                    "interrupted",
                    False,
                )
                assert reported.ticks == len(ticks) and reported.note == ORPHAN_NOTE


def test_kill9_mid_trial_then_resume_loses_nothing(tmp_path: Path) -> None:
    db = tmp_path / "study.db"
    proc = start(db)
    wait_for(db, proc, lambda s: bool(s["completed"]))
    # a second process opening the same session is refused while this one lives
    second = start(db, "--resume")
    out, err = second.communicate(timeout=60)
    assert second.returncode == 2
    last = json.loads(out.strip().splitlines()[-1])
    assert last["status"] == "error" and f"process {proc.pid}" in last["error"]
    assert "already open" in err
    # 1. kill while a task trial (after training and its ratings) runs with samples on disk;
    #    a trial may end between our look and the kill: then resume and try the next one
    running = None
    for _ in range(8):
        before = wait_for(
            db,
            proc,
            lambda s: (
                s["running"] is not None and s["running"].phase == "task" and s["samples"] > 30
            ),
        )
        kill(proc)
        check_after_kill(db, before)
        with Store.open_readonly(db) as store:
            left = store.trial(before["running"].trial_id, raw=True)
            if left.status == "running":
                running = left
                assert store.sample_count(left.trial_id) >= before["samples"]
                assert store.session("P01").cursor == left.step  # its place in the schedule
                exported = tidy_tables(store)["trials"].set_index("trial_id").loc[left.trial_id]
                assert (exported["status"], exported["outcome"]) == ("interrupted", "interrupted")
                assert exported["ticks"] == store.sample_count(left.trial_id)
                assert store.trial(left.trial_id, raw=True).status == "running"  # not written
                break
        proc = start(db, "--resume")
    assert running is not None, "never caught a trial mid-run"
    # 2. resume, and kill again at random moments until the session ends by itself
    rng = random.Random(7)
    for _ in range(3):
        proc = start(db, "--resume")
        time.sleep(rng.uniform(0.5, 3.0))  # startup, reopen, scene build or trial
        before = snapshot(db)
        if proc.poll() is not None:
            break
        kill(proc)
        check_after_kill(db, before)
        if session_status(db) == "completed":  # it finished between our look and the kill
            proc = None
            break
    else:
        proc = start(db, "--resume", realtime=False)  # the rest of the session, unpaced
    if proc is not None:
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        summary = json.loads(out.strip().splitlines()[-1])
        assert summary == {
            "participant": "P01",
            "trials_completed": 11,
            "ratings": 31,
            "status": "completed",
        }
    with Store.open_readonly(db) as store:
        assert store.integrity_check() == "ok"
        assert store.session("P01").status == "completed" and len(store.ratings()) == 31
        trials = store.trials()
        first = store.trial(running.trial_id)
        assert (first.status, first.outcome) == ("interrupted", "interrupted")
        assert first.ticks == store.sample_count(first.trial_id) > 30
        redo = [t for t in trials if t.step == running.step and t.status == "completed"]
        assert len(redo) == 1 and redo[0].attempt > 1
        assert (redo[0].task, redo[0].mode, redo[0].run) == (
            running.task,
            running.mode,
            running.run,
        )
        # every schedule step has exactly one completed trial, in schedule order
        done = [t for t in trials if t.status == "completed"]
        assert [t.step for t in done] == sorted({t.step for t in done}) and len(done) == 11
        assert [t.position for t in done if t.phase == "task"] == list(range(1, 9))
        assert not [t for t in trials if t.status == "running"]
        kinds = [e.kind for e in store.events()]
        assert kinds.count("reopen") >= 1 and kinds[-1] == "finish"
        reopen = next(e for e in store.events() if e.kind == "reopen" and e.detail["interrupted"])
        assert reopen.detail["interrupted"] == [running.trial_id]
        assert reopen.detail["cursor"] == running.step and "took_over" in reopen.detail

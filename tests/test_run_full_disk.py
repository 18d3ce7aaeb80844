"""``python -m study run`` on a disk that fills up mid-session, then ``--resume`` once freed.

The disk is "full" through SQLite's own limit (``max_page_count`` on the connection the command
opens), so the failure takes SQLite's real ``SQLITE_FULL`` path in whichever write hits it first
(a sample batch, a trial's end, an answer). The command must print its error on stderr and its
JSON line on stdout, exit 2 without a traceback, leave a consistent store, and ``--resume``
must finish the session without losing a completed trial or rating.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from study.__main__ import main as study_main
from study.cli import run as run_cli
from study.store import Store
from tests.disk_full import cap


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict[str, Any], str]:
    code = study_main(list(argv))
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert len(lines) == 1, out
    return code, json.loads(lines[0]), err


def full_after(extra_pages: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the store the next command opens full once it grew by ``extra_pages`` pages."""
    real = run_cli.open_store

    def open_capped(path: Any, protocol: Any, **kw: Any) -> Store:
        store = real(path, protocol, **kw)
        cap(store, extra_pages=extra_pages)
        return store

    monkeypatch.setattr(run_cli, "open_store", open_capped)  # where the command opens it


def done(db: Path) -> tuple[set[tuple], set[tuple]]:
    with Store.open_readonly(db) as store:
        assert store.integrity_check() == "ok"
        trials = {
            (t.trial_id, t.step, t.attempt, t.outcome, t.ticks, store.sample_count(t.trial_id))
            for t in store.trials()
            if t.status == "completed"
        }
        ratings = {(r.rating_id, r.step, r.item, r.value) for r in store.ratings()}
    return trials, ratings


@pytest.mark.parametrize("extra_pages", [40, 300])
def test_run_reports_a_full_disk_and_resume_finishes(
    extra_pages: int,
    tmp_path: Path,
    short_protocol: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    db = tmp_path / "study.db"
    args = ["--protocol", str(short_protocol), "--db", str(db), "--participant", "P01"]
    with monkeypatch.context() as patch:
        full_after(extra_pages, patch)
        code, summary, err = run(capsys, "run", *args, "--seed", "2")
    assert code == 2
    assert summary["status"] == "error"
    assert "the disk is full" in summary["error"]
    assert "Free space on the disk holding" in summary["error"]
    assert summary["participant"] == "P01"
    assert summary["trials_completed"] < 11
    assert "error: " in err and "the disk is full" in err
    assert "Traceback" not in err
    trials_before, ratings_before = done(db)
    assert len(trials_before) == summary["trials_completed"]
    assert len(ratings_before) == summary["ratings"]
    # each completed trial kept all its samples
    assert all(ticks == samples for *_, ticks, samples in trials_before)

    code, summary, err = run(capsys, "run", *args, "--resume")
    assert code == 0, err
    assert summary == {
        "participant": "P01",
        "trials_completed": 11,
        "ratings": 31,
        "status": "completed",
    }
    trials_after, ratings_after = done(db)
    assert trials_before <= trials_after
    assert ratings_before <= ratings_after
    assert len(trials_after) == 11

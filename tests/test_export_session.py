"""End to end: a whole headless session (study run) exported to tidy tables the analysis reads."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from study.export import tidy_tables
from study.protocol import load_protocol

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"


@pytest.mark.slow
def test_session_export_has_every_condition_rating_and_covariate(tmp_path: Path) -> None:
    db = tmp_path / "study.sqlite"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "study",
            "run",
            "--protocol",
            str(PAPER),
            "--db",
            str(db),
            "--participant",
            "P01",
            "--seed",
            "1",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    out = tmp_path / "export"
    export = subprocess.run(
        [
            sys.executable,
            "-m",
            "study",
            "export",
            "--db",
            str(db),
            "--out",
            str(out),
            "--protocol",
            str(PAPER),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert export.returncode == 0, export.stderr
    protocol = load_protocol(PAPER)
    trials = pd.read_parquet(out / "trials.parquet")
    pd.testing.assert_frame_equal(trials, tidy_tables(db)["trials"], check_dtype=False)

    assert (trials["phase"] == "training").sum() == protocol.training.runs
    tasks = trials[(trials["phase"] == "task") & (trials["status"] == "completed")]
    cells = set(zip(tasks["task"], tasks["mode"], strict=True))
    assert cells == {(t, m) for t in protocol.task_names for m in protocol.mode_names}
    assert sorted(tasks["position"]) == list(range(1, 9))
    assert list(tasks.sort_values("position")["tasks_completed"]) == list(range(8))
    for item in ("helpful", "matched", "teammate", "preference"):
        assert tasks[item].between(1, 7).all(), item
    assert tasks["preference_aggressive"].between(-3, 3).all()
    # both runs of a task carry the same preference
    assert (tasks.groupby("task")["preference"].nunique() == 1).all()
    assert trials["training_time_s"].notna().all() and trials["baseline_rating"].notna().all()

    samples = pd.read_parquet(out / "samples.parquet")
    assert len(samples) == trials["ticks"].sum()
    names = set().union(*(json.loads(g) for g in trials["goal_names"]))
    assert set(samples["predicted"].dropna()) <= names
    probs = samples.filter(like="prob_").fillna(0).sum(axis=1)
    assert probs.round(6).eq(1).all()
    ratings = pd.read_parquet(out / "ratings.parquet")
    assert len(ratings) == 3 + 8 * 3 + 4
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["protocol_hash"] == protocol.content_hash

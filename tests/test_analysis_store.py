"""Integration: a real study store written by `python -m study run` (scripted participant),
read through study.export.tidy_tables, analysed and reported. The store is written by a new
process as a user writes it; the report and export command lines then run their ``main`` in
this process (no interpreter start-up and imports each, 2-3 CPU s a command)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from analysis.__main__ import main as analysis_main
from analysis.load import load_tables, task_cells
from analysis.prediction_eval import evaluate_predictions
from study.__main__ import main as study_main
from tests.support.cli import run_main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp("store") / "study.db"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "study",
            "run",
            "--db",
            str(db),
            "--participant",
            "P01",
            "--seed",
            "3",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    return db


def test_store_loads_into_the_contract_tables(store: Path) -> None:
    tables = load_tables(db=store)
    assert tables.protocol_hash and len(tables.protocol_hash) == 64
    cells, _ = task_cells(tables.trials)
    assert len(cells) == 8
    assert set(zip(cells["task"], cells["mode"], strict=True)) == {
        (t, m)
        for t in ("easy-right", "easy-wrong", "hard-right", "hard-wrong")
        for m in ("timid", "aggressive")
    }
    assert (tables.trials[tables.trials.phase == "training"]["mode"] == "none").all()
    evals, notes = evaluate_predictions(cells, tables.samples, workers=1)
    assert notes == () and len(evals) == 16
    assert evals["success_rate"].between(0, 1).all()
    ticks = tables.samples.groupby("trial_id").size()
    assert (
        evals.set_index("trial_id")["n_ticks"].groupby(level=0).first()
        == ticks.reindex(evals["trial_id"].unique())
    ).all()


def test_report_from_a_one_participant_store(
    store: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = run_main(analysis_main, ["report", "--db", str(store), "--out", str(tmp_path)], capsys)
    assert run.returncode == 0, run.stderr
    doc = json.loads((tmp_path / "results.json").read_text())
    assert doc["participants"] == 1
    # one participant carries no test: none is run, and the report says why
    assert any(
        "no tests, p-values or confidence intervals: 1 participant" in n for n in doc["notes"]
    )
    assert doc["statistics"] == []
    html = (tmp_path / "report.html").read_text()
    assert html.count("<svg") == 4  # Fig. 7 (protocol), Fig. 8 (time, ratings), Fig. 9 (replays)
    assert "Success rate and time to a lasting correct prediction" in html  # descriptive
    assert "Statistical tests: not computed" in html and "Data quality per participant" in html


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_exported_files_give_the_same_numbers_as_the_store(
    store: Path, tmp_path: Path, fmt: str, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["export", "--db", str(store), "--out", str(tmp_path), "--format", fmt]
    run = run_main(study_main, argv, capsys)
    assert run.returncode == 0, run.stderr
    from_db, from_files = load_tables(db=store), load_tables(export_dir=tmp_path)
    assert from_files.protocol_hash == from_db.protocol_hash
    a, _ = task_cells(from_db.trials)
    b, _ = task_cells(from_files.trials)
    cols = ["participant", "task", "mode", "duration_s", "preference_aggressive", "trial_id"]
    pd.testing.assert_frame_equal(
        a[cols].reset_index(drop=True), b[cols].reset_index(drop=True), check_dtype=False
    )
    ea, _ = evaluate_predictions(a, from_db.samples, workers=1)
    eb, _ = evaluate_predictions(b, from_files.samples, workers=1)
    pd.testing.assert_frame_equal(ea, eb, check_dtype=False)

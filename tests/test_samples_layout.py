"""The samples layout declared once: store, writer, export, codebook and reader agree with it,
and a store that predates a declared column still opens."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from app.teleop import ScriptedInput
from app.trial import TrialConfig, records_from_samples, run_trial
from app.trial.samples import SAMPLE_COLUMNS, SAMPLE_DOCS, SAMPLE_FIELDS, SampleLayoutError
from study.codebook import codebook
from study.export import tidy_tables
from study.protocol import trial_config_from_protocol
from study.session.sample_writer import sample_row
from study.store import Store
from tests.support.stores import enrol, new_trial, open_store

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def result():
    config: TrialConfig = trial_config_from_protocol(
        ROOT / "protocols" / "dragan2013.toml", "easy-right", "timid"
    )
    return run_trial(config, ScriptedInput(seed=3))


def test_a_stored_trial_reads_back_field_for_field(result, tmp_path: Path) -> None:
    with open_store(tmp_path / "s.db") as store:
        tid = new_trial(store, enrol(store))
        store.insert_samples([sample_row(tid, k, r) for k, r in enumerate(result.records)])
        read = records_from_samples(store.samples(tid))
    assert len(read) == len(result.records)
    for k, (a, b) in enumerate(zip(result.records, read, strict=True)):
        assert b.tick == k
        for f in SAMPLE_FIELDS:
            x, y = getattr(a, f.attr), getattr(b, f.attr)
            np.testing.assert_equal(y, x, err_msg=f"tick {k}: {f.attr}")  # nan == nan


def test_store_export_and_codebook_columns_come_from_the_layout(result, tmp_path: Path) -> None:
    path = tmp_path / "s.db"
    with open_store(path) as store:
        tid = new_trial(store, enrol(store))
        store.insert_samples([sample_row(tid, k, r) for k, r in enumerate(result.records[:5])])
        assert list(store.samples().columns) == ["trial_id", "tick", *SAMPLE_COLUMNS]
        declared = [r[1] for r in store.conn.execute("PRAGMA table_info(samples)")]
    assert sorted(declared) == sorted(["trial_id", "tick", *SAMPLE_COLUMNS])
    samples = tidy_tables(Store.open_readonly(path))["samples"]
    spread = [c for c in samples.columns if c.startswith("prob_")]
    assert spread == ["prob_0", "prob_1"]
    expected = [c for c in SAMPLE_COLUMNS for c in (spread if c == "probabilities" else [c])]
    assert list(samples.columns) == ["trial_id", "participant", "tick", *expected]
    book = codebook({"samples": samples}).set_index("column")
    for column, (description, unit) in SAMPLE_DOCS.items():
        if column not in ("predicted", "probabilities"):  # the export writes these its own way
            assert book.loc[column, "description"] == description
            assert book.loc[column, "values"] == unit
    assert book.loc["q7", "description"] == "robot configuration Q, joint 7"
    assert book.loc["target_z", "values"] == "m"


def test_a_store_without_a_declared_column_opens_and_gains_it(result, tmp_path: Path) -> None:
    """A file written before a column was declared (here: ``gripper`` taken out again) reads
    the column as empty, and opened read-write it gets the column for the ticks to come."""
    path = tmp_path / "old.db"
    with open_store(path) as store:
        tid = new_trial(store, enrol(store))
        store.insert_samples([sample_row(tid, k, r) for k, r in enumerate(result.records[:3])])
    with sqlite3.connect(path) as conn:
        conn.execute("ALTER TABLE samples DROP COLUMN gripper")
    old = Store.open_readonly(path).samples(tid)
    assert list(old.columns) == ["trial_id", "tick", *SAMPLE_COLUMNS]
    assert old["gripper"].isna().all() and old["alpha"].notna().all()
    with open_store(path) as store:
        store.insert_samples([sample_row(tid, 3, result.records[3])])
        now = store.samples(tid)
    assert now["gripper"].isna().tolist() == [True, True, True, False]
    assert now["gripper"].iloc[3] == pytest.approx(result.records[3].gripper)


def test_a_table_missing_a_column_is_refused_by_name() -> None:
    frame = pd.DataFrame({"tick": [0], "t": [0.0]})
    with pytest.raises(SampleLayoutError, match="'q1'"):
        records_from_samples(frame)

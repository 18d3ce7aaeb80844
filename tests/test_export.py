"""Export: a small store written through study.store becomes tidy tables, files and a codebook."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest

from study.__main__ import main as study_main
from study.codebook import CodebookError, codebook
from study.export import TRIAL_COLUMNS, ExportError, tidy_tables
from study.protocol import load_protocol
from study.retention import RetentionError, record_retention
from study.store import Store
from tests.support.cli import run_main
from tests.support.exports import PAPER, ROOT, build_store


@pytest.fixture(scope="module")
def protocol():
    return load_protocol(PAPER)


@pytest.fixture(scope="module")
def store_path(tmp_path_factory, protocol):
    path = tmp_path_factory.mktemp("store") / "study.sqlite"
    info = build_store(path, protocol)
    return path, info


def test_the_papers_protocol_exports_exactly_the_papers_factor_columns(store_path) -> None:
    """Factors are exported by name (issue 25); the paper's three are today's columns, in place."""
    path, _ = store_path
    trials = tidy_tables(path)["trials"]
    assert tuple(trials.columns[: len(TRIAL_COLUMNS)]) == TRIAL_COLUMNS
    assert TRIAL_COLUMNS[5:9] == ("task", "difficulty", "correctness", "mode")
    training = trials[trials["phase"] == "training"]
    assert training["difficulty"].isna().all() and (training["mode"] == "none").all()


def test_trials_table_columns_and_covariates(store_path, protocol) -> None:
    path, info = store_path
    tables = tidy_tables(path)
    assert set(tables) == {
        "trials",
        "samples",
        "ratings",
        "answers",
        "participants",
        "events",
        "sessions",
    }
    assert tables["participants"]["included"].all()
    trials = tables["trials"]
    contract = [
        "participant",
        "session_id",
        "phase",
        "schedule_row",
        "position",
        "task",
        "difficulty",
        "correctness",
        "mode",
        "attempt",
        "status",
        "outcome",
        "success",
        "duration_s",
        "started_at",
        "goal_names",
        "goal_positions",
        "target",
        "training_time_s",
        "baseline_rating",
        "tasks_completed",
        "helpful",
        "matched",
        "teammate",
        "preference",
        "preference_aggressive",
        "trial_id",
    ]
    assert [c for c in trials.columns if c in contract] == contract
    p1 = trials[trials["participant"] == "P01"]
    assert len(p1) == 3 + 3  # three training runs, one redone and two completed task runs
    assert (p1["training_time_s"] == 40.0).all()
    assert (p1["baseline_rating"] == 3.0).all()
    training = p1[p1["phase"] == "training"]
    assert (training["mode"] == "none").all() and training["position"].isna().all()
    tasks = p1[p1["phase"] == "task"].reset_index(drop=True)
    assert list(tasks["status"]) == ["redone", "completed", "completed"]
    assert list(tasks["tasks_completed"]) == [0, 0, 1]
    assert list(tasks["attempt"]) == [1, 2, 1]
    assert tasks["success"].tolist() == [False, True, True]
    # per-condition ratings sit on the trial they rate; the redone attempt has none
    assert tasks["helpful"].isna().tolist() == [True, False, False]
    assert list(tasks["helpful"][1:]) == [6, 7]
    assert tasks.loc[1:, "matched"].tolist() == [4, 4]
    # the preference sits on both runs: 2 = "Preferred the first run"
    assert (tasks["preference"] == 2).all()
    expected = 2.0 if info["first_mode"] == "aggressive" else -2.0
    assert (tasks["preference_aggressive"] == expected).all()
    assert json.loads(tasks["goal_names"][0]) == list(protocol.goal_names(info["task"]))
    assert tasks["target"][0] == protocol.scenes[protocol.tasks[0].scene].target
    p2 = trials[trials["participant"] == "P02"]
    assert list(p2["status"]) == ["interrupted"] and p2["training_time_s"].isna().all()
    assert list(p2["schedule_row"]) == [1]


def test_samples_table(store_path, protocol) -> None:
    path, info = store_path
    samples = tidy_tables(path)["samples"]
    assert len(samples) == 9
    names = protocol.goal_names(info["task"])
    assert list(samples["predicted"][:3]) == [names[0], names[1], names[0]]
    assert samples["prob_0"].tolist() == [0.7] * 9 and samples["prob_1"].tolist() == [0.3] * 9
    assert "prob_2" not in samples.columns
    assert set(samples["participant"]) == {"P01"}
    assert samples.loc[2, "q3"] == pytest.approx(0.2)
    assert json.loads(samples.loc[2, "events"]) == ["grasp"]
    for c in ("q7", "u1", "p4", "cmd7", "target_x", "ee_z", "gripper", "alpha", "confidence"):
        assert c in samples.columns


def test_ratings_and_events_tables(store_path) -> None:
    path, _ = store_path
    tables = tidy_tables(path)
    ratings = tables["ratings"]
    assert list(ratings.columns[:9]) == [
        "participant",
        "session_id",
        "phase",
        "task",
        "mode",
        "run",
        "item",
        "value",
        "answered_at",
    ]
    assert len(ratings) == 3 + 6 + 1
    pref = ratings[ratings["item"] == "preference"]
    assert pref["run"].isna().all() and pref["mode"].isna().all()
    events = tables["events"]
    assert list(events.columns) == ["participant", "session_id", "at", "kind", "detail"]
    assert "withdraw" in set(events["kind"])
    assert json.loads(events[events["kind"] == "withdraw"]["detail"].iloc[0]) == {
        "reason": "felt unwell"
    }


def test_export_without_the_protocol_infers_the_same_tables(store_path) -> None:
    path, _ = store_path
    inferred = tidy_tables(path, search=[])  # no protocol file: items inferred from the data
    known = tidy_tables(path)
    pd.testing.assert_frame_equal(inferred["trials"], known["trials"])
    book = codebook(inferred)
    assert book["column"].tolist()[: len(inferred["trials"].columns)] == list(
        inferred["trials"].columns
    )


def test_codebook_describes_every_column(store_path, protocol) -> None:
    path, _ = store_path
    tables = tidy_tables(path)
    book = codebook(tables, protocol=protocol)
    for name, df in tables.items():
        described = book[book["table"] == name]["column"].tolist()
        assert described == list(df.columns)
    assert (book["description"].str.len() > 10).all()
    helpful = book[(book["table"] == "trials") & (book["column"] == "helpful")].iloc[0]
    assert "How helpful was the robot?" in helpful["description"]
    assert "1 = Not at all helpful" in helpful["values"]
    pref = book[book["column"] == "preference_aggressive"].iloc[0]
    assert pref["values"] == "-3..+3"
    with pytest.raises(CodebookError, match="'mystery'"):
        codebook({"events": pd.DataFrame(columns=["mystery"])})


def test_wrong_protocol_is_refused(store_path) -> None:
    path, _ = store_path
    other = load_protocol(ROOT / "protocols" / "memory3.toml")
    with pytest.raises(ExportError, match="not by"):
        tidy_tables(path, protocol=other)


def test_export_cli_writes_csv_parquet_and_codebook(store_path, tmp_path) -> None:
    path, _ = store_path
    out = tmp_path / "export"
    proc = subprocess.run(
        [sys.executable, "-m", "study", "export", "--db", str(path), "--out", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["rows"] == {
        "trials": 7,
        "samples": 9,
        "ratings": 10,
        "answers": 2,
        "participants": 2,
        "events": 3,  # consent, withdraw, the retention answer P02 gave in person
        "sessions": 2,
    }
    tables = tidy_tables(path)
    for name, df in tables.items():
        parquet = pd.read_parquet(out / f"{name}.parquet")
        pd.testing.assert_frame_equal(parquet, df, check_dtype=False)
        csv = pd.read_csv(out / f"{name}.csv")
        assert list(csv.columns) == list(df.columns) and len(csv) == len(df)
    book = pd.read_csv(out / "codebook.csv")
    assert len(book) == sum(len(df.columns) for df in tables.values())
    md = (out / "codebook.md").read_text()
    assert "## trials" in md and "`preference_aggressive`" in md
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["protocol_hash"] == load_protocol(PAPER).content_hash
    assert meta["rows"] == summary["rows"]


def test_export_cli_reports_a_missing_store(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    # the export command line's main in this process (the command that writes files above is a
    # new process, as a user runs it)
    argv = ["export", "--db", str(tmp_path / "none.sqlite"), "--out", str(tmp_path / "out")]
    proc = run_main(study_main, argv, capsys)
    assert proc.returncode == 2 and "no store at" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_empty_store_exports_empty_tables_with_columns(tmp_path, protocol) -> None:
    path = tmp_path / "empty.sqlite"
    Store.open(path, protocol_id=protocol.id, protocol_hash=protocol.content_hash).close()
    tables = tidy_tables(path)
    assert all(len(df) == 0 for df in tables.values())
    assert "preference_aggressive" in tables["trials"].columns
    assert "trial_id" in tables["samples"].columns


def test_a_retention_answer_is_recorded_once_and_only_after_the_session(
    store_path, protocol, tmp_path
) -> None:
    path, _ = store_path
    answers = {a.participant: a for a in Store.open_readonly(path).answers()}
    recorded = answers["P02"]
    assert (recorded.questionnaire, recorded.step) == ("recorded", -1)
    assert recorded.value == protocol.questionnaire.retention.keep
    with Store.open(path, protocol_id=protocol.id, protocol_hash=protocol.content_hash) as store:
        with pytest.raises(RetentionError, match="already answered"):
            record_retention(store, protocol, "P02", keep=False)
        events = [e for e in store.events(participant="P02") if e.kind == "retention_recorded"]
        assert events[0].detail == {"item": "keep_data", "keep": True, "by": "experimenter"}
    db = tmp_path / "running.db"
    build_store(db, protocol)
    with Store.open(db, protocol_id=protocol.id, protocol_hash=protocol.content_hash) as store:
        with store.transaction() as tx:
            tx.update_session(store.session("P01").session_id, status="running")
            tx.cur.execute("DELETE FROM answers WHERE participant = 'P01'")
        with pytest.raises(RetentionError, match="asks the retention question at its end"):
            record_retention(store, protocol, "P01", keep=True)

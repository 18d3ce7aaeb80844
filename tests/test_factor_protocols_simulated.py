"""The three protocols of issue 25 run end to end: simulated participants through the same code
paths as a live study, then exported with one column per declared factor."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from analysis import load_tables
from analysis.report import write_report
from study.codebook import codebook
from study.export import tidy_tables
from study.protocol import load_protocol
from study.simulated import simulate

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"


def _store(tmp_path_factory: pytest.TempPathFactory, name: str, participants: int) -> Path:
    db = tmp_path_factory.mktemp(name) / "sim.db"
    report = simulate(
        protocol_path=PROTOCOLS / f"{name}.toml",
        db=db,
        participants=participants,
        seed=3,
        progress=False,
    )
    assert report.errors == [] and report.error is None
    return db


def _trials(tmp_path_factory: pytest.TempPathFactory, name: str, participants: int) -> pd.DataFrame:
    return tidy_tables(_store(tmp_path_factory, name, participants))["trials"]


def test_intent_mode_crosses_the_cue_with_the_modes_in_every_task(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    trials = _trials(tmp_path_factory, "intent_mode", 1)
    tasks = trials[trials["phase"] == "task"]
    assert list(trials.columns[5:10]) == ["task", "difficulty", "correctness", "mode", "cue"]
    assert len(tasks) == 16 and (tasks["status"] == "completed").all()
    # the mode column holds the arbitration's level, the cue its own
    assert set(tasks["mode"]) == {"timid", "aggressive"}
    cells = tasks.groupby(["task", "mode", "cue"]).size()
    assert len(cells) == 16 and (cells == 1).all()
    training = trials[trials["phase"] == "training"]
    assert (training["mode"] == "none").all() and training["cue"].isna().all()


def test_mapping_mode_gives_each_participant_one_mapping_for_all_their_runs(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    tables = tidy_tables(_store(tmp_path_factory, "mapping_mode", 2))
    trials = tables["trials"]
    assert "mapping" in trials.columns
    # the participants table carries each participant's group, after their schedule row
    people = tables["participants"]
    assert list(people.columns[:4]) == ["participant", "session_id", "schedule_row", "mapping"]
    assert people.set_index("schedule_row")["mapping"].to_dict() == {0: "absolute", 1: "relative"}
    book = codebook(tables, protocol=load_protocol(PROTOCOLS / "mapping_mode.toml"))
    described = book[book["column"] == "mapping"].set_index("table")["description"]
    assert "between subjects; the participant's level on every row" in described["trials"]
    assert "between subjects" in described["participants"]
    by_person = trials.groupby("participant")["mapping"].agg(lambda s: tuple(sorted(set(s))))
    assert sorted(by_person) == [("absolute",), ("relative",)]  # training rows included
    assert (trials.groupby("participant").size() == 11).all()
    assert (trials[trials["phase"] == "task"]["status"] == "completed").all()


def test_goals_mode_runs_two_and_four_object_scenes_in_a_williams_order_and_is_reported(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    db = _store(tmp_path_factory, "goals_mode", 3)  # 3: the fewest the report tests
    trials = tidy_tables(db)["trials"]
    tasks = trials[trials["phase"] == "task"]
    assert "difficulty" not in trials.columns and "goals" in trials.columns
    goals = tasks.set_index("goals")["goal_names"].map(lambda s: len(json.loads(s)))
    assert set(goals.loc["goals2"]) == {2} and set(goals.loc["goals4"]) == {4}
    # the participants take different rows of the square: different first conditions
    first = tasks[tasks["position"] == 1][["goals", "mode"]].apply(tuple, axis=1)
    assert first.nunique() == 3
    assert (tasks["status"] == "completed").all()
    # reported by its own factors, not the paper's
    out = tmp_path_factory.mktemp("goals_report")
    write_report(load_tables(db=db), out)
    report = (out / "report.md").read_text()
    assert "## ANOVA by factor" in report and "## Post-hoc comparisons by factor" in report
    assert "| goals | within subjects | goals2, goals4 |" in report
    assert "| goals:mode | goals:mode x subjects |" in report
    assert "| difficulty |" not in report and "easy" not in report

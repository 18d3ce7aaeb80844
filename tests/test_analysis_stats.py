"""Paired comparisons, correlations, loading and the paper's timing analysis on synthetic
tables in the contract's tidy schema (references: scipy's own tests and hand arithmetic)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.correlations import pearson, preference_correlations
from analysis.errors import DesignError, SchemaError, SourceError
from analysis.load import from_export, from_frames, load_tables, task_cells
from analysis.posthoc import Comparison, paired_comparisons, paired_t
from analysis.synthetic import synthetic_tables
from analysis.timing import timing_analysis

CONTRACT_TRIAL_COLUMNS = [
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
CONTRACT_SAMPLE_COLUMNS = [
    "trial_id",
    "participant",
    "tick",
    "t",
    *[f"{p}{i}" for p in ("q", "u", "p", "cmd") for i in range(1, 8)],
    "alpha",
    "confidence",
    "predicted",
    "prob_0",
    "prob_1",
    "target_x",
    "target_y",
    "target_z",
    "ee_x",
    "ee_y",
    "ee_z",
    "gripper",
    "events",
]


@pytest.fixture(scope="module")
def study() -> dict[str, pd.DataFrame]:
    """A simulated 8-participant study in the contract's tidy schema (20 Hz samples)."""
    return synthetic_tables(8, seed=11, rate_hz=20.0)


def test_fixture_follows_the_contract_schema(study: dict[str, pd.DataFrame]) -> None:
    assert set(CONTRACT_TRIAL_COLUMNS) <= set(study["trials"].columns)
    assert set(CONTRACT_SAMPLE_COLUMNS) <= set(study["samples"].columns)
    assert {
        "participant",
        "session_id",
        "phase",
        "task",
        "mode",
        "run",
        "item",
        "value",
        "answered_at",
    } <= set(study["ratings"].columns)


def test_paired_t_matches_scipy_and_hand_values() -> None:
    a = np.array([12.0, 15.5, 9.0, 20.0, 14.0, 11.0, 17.5, 13.0])
    b = np.array([10.0, 12.0, 9.5, 15.0, 13.0, 8.0, 14.0, 12.5])
    r = paired_t(a, b)
    ref = stats.ttest_rel(a, b)
    assert r["t"] == pytest.approx(ref.statistic) and r["p"] == pytest.approx(ref.pvalue)
    ci = ref.confidence_interval(0.95)
    assert (r["ci_low"], r["ci_high"]) == pytest.approx((ci.low, ci.high))
    d = a - b  # d_z by hand: mean 2.25, sd of the differences
    assert r["d_z"] == pytest.approx(d.mean() / d.std(ddof=1))
    assert r["df"] == 7 and r["mean_diff"] == pytest.approx(2.25)


def test_bonferroni_multiplies_within_family_and_caps_at_one() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=10)
    out = paired_comparisons(
        [
            Comparison("f1", "big", x + 1.0 + rng.normal(0, 0.3, 10), x),
            Comparison("f1", "none", x + rng.normal(0, 1, 10), x),
            Comparison("f2", "alone", x + rng.normal(0, 1, 10), x),
        ]
    ).set_index("comparison")
    assert list(out["m"]) == [2, 2, 1]
    assert out.loc["big", "p_bonf"] == pytest.approx(2 * out.loc["big", "p"])
    assert out.loc["alone", "p_bonf"] == pytest.approx(out.loc["alone", "p"])
    assert (out["p_bonf"] <= 1).all()


def test_pearson_matches_scipy() -> None:
    rng = np.random.default_rng(4)
    x = rng.normal(size=32)
    y = 0.6 * x + rng.normal(size=32)
    r = pearson(x, y)
    ref = stats.pearsonr(x, y)
    assert r["r"] == pytest.approx(ref.statistic) and r["p"] == pytest.approx(ref.pvalue)
    assert r["df"] == 30
    ci = ref.confidence_interval(0.95)
    assert (r["ci_low"], r["ci_high"]) == pytest.approx((ci.low, ci.high), rel=1e-6)


def test_timing_analysis_has_the_papers_degrees_of_freedom(study: dict[str, pd.DataFrame]) -> None:
    cells, _ = task_cells(from_frames(study["trials"]).trials)
    assert len(cells) == 64
    t = timing_analysis(cells)
    assert set(t.ancova.table["df2"]) == {53}
    assert set(t.rm.table["df2"]) == {7}
    assert 0 < t.ancova.r2 < 1
    comp = t.comparisons.set_index("comparison")
    assert set(comp[comp.analysis == "timing_posthoc"]["df"]) == {15}
    assert set(comp[comp.analysis == "timing_posthoc_subject"]["df"]) == {7}  # reviewer's form
    assert set(comp[comp.family.str.startswith("planned")]["df"]) == {7}
    # The simulated study slows aggressive-and-wrong down: every comparison against it is > 0.
    assert (comp[comp.family.str.startswith("post-hoc")]["t"] > 0).all()
    hr = comp.loc["Hard&Right: aggressive - timid"]
    w = cells[cells.task == "hard-right"].pivot_table(
        index="participant", columns="mode", values="duration_s"
    )
    assert hr["mean_diff"] == pytest.approx((w["aggressive"] - w["timid"]).mean())
    eff = t.main_effects.set_index("factor")
    hard = cells[cells.difficulty == "hard"]["duration_s"].mean()
    easy = cells[cells.difficulty == "easy"]["duration_s"].mean()
    assert eff.loc["difficulty", "mean_diff"] == pytest.approx(hard - easy)


def test_timing_drops_incomplete_participants_with_a_note(study: dict[str, pd.DataFrame]) -> None:
    trials = study["trials"].copy()
    gone = (
        (trials.participant == "P03") & (trials.task == "easy-wrong") & (trials["mode"] == "timid")
    )
    trials.loc[gone, "status"] = "interrupted"
    cells, notes = task_cells(from_frames(trials).trials)
    assert any("interrupted" in n for n in notes)
    t = timing_analysis(cells)
    assert set(t.rm.table["df2"]) == {6}
    assert set(t.ancova.table["df2"]) == {56 - 8 - 3}
    assert any("P03" in n for n in t.notes)


def test_constant_covariate_is_left_out_with_a_note(study: dict[str, pd.DataFrame]) -> None:
    cells, _ = task_cells(from_frames(study["trials"].assign(baseline_rating=4.0)).trials)
    t = timing_analysis(cells)
    assert t.covariates == ("training_time_s", "tasks_completed")
    assert set(t.ancova.table["df2"]) == {54}
    assert any("baseline_rating" in n and "constant" in n for n in t.notes)


def test_preference_correlations_are_r30(study: dict[str, pd.DataFrame]) -> None:
    cells, _ = task_cells(from_frames(study["trials"]).trials)
    table, frame = preference_correlations(cells)
    assert len(frame) == 32 and set(table["df"]) == {30}
    first = table.iloc[0]
    assert first["r"] == pytest.approx(
        stats.pearsonr(frame["preference_aggressive"], frame["time_advantage_aggressive"])[0]
    )
    assert set(table["measure"]) == {
        "preference_aggressive",
        "helpful_diff",
        "matched_diff",
        "teammate_diff",
    }
    with pytest.raises(SchemaError, match="preference_aggressive"):
        preference_correlations(cells.drop(columns="preference_aggressive"))


def test_export_directory_round_trip(tmp_path: Path, study: dict[str, pd.DataFrame]) -> None:
    study["trials"].to_csv(tmp_path / "trials.csv", index=False)
    study["samples"].to_parquet(tmp_path / "samples.parquet")
    study["ratings"].to_csv(tmp_path / "ratings.csv", index=False)
    (tmp_path / "codebook.json").write_text(json.dumps({"protocol_hash": "abc123"}))
    t = from_export(tmp_path)
    assert t.protocol_hash == "abc123"
    assert isinstance(t.trials["goal_names"].iloc[5], list)
    assert t.trials["success"].dtype == bool
    assert len(t.samples) == len(study["samples"])
    assert t.events.empty
    with pytest.raises(SourceError, match="exactly one"):
        load_tables()
    with pytest.raises(SourceError, match="not a directory"):
        from_export(tmp_path / "ratings.csv")
    (tmp_path / "empty").mkdir()
    with pytest.raises(SourceError, match="no trials"):
        from_export(tmp_path / "empty")
    with pytest.raises(SourceError, match="--db"):
        load_tables(db=tmp_path / "absent.db")


def test_missing_trial_columns_are_named(study: dict[str, pd.DataFrame]) -> None:
    with pytest.raises(SchemaError, match="'duration_s'"):
        from_frames(study["trials"].drop(columns="duration_s"))
    with pytest.raises(DesignError):
        timing_analysis(
            task_cells(from_frames(study["trials"][study["trials"].participant == "P01"]).trials)[0]
        )


def test_unsuccessful_trials_are_kept_with_a_note_or_left_out(
    study: dict[str, pd.DataFrame],
) -> None:
    trials = study["trials"].copy()
    bad = (
        (trials.participant == "P02")
        & (trials.task == "hard-wrong")
        & (trials["mode"] == "aggressive")
    )
    trials.loc[bad, ["success", "outcome"]] = [False, "timeout"]
    kept, notes = task_cells(from_frames(trials).trials)
    assert len(kept) == 64 and any("1 timeout" in n and "as is" in n for n in notes)
    only, notes2 = task_cells(from_frames(trials).trials, successful_only=True)
    assert len(only) == 63 and any("left out" in n for n in notes2)
    assert set(timing_analysis(only).rm.table["df2"]) == {6}

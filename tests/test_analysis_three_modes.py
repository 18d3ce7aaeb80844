"""The report on a 2 x 2 x 3 design (the adaptive protocol's shape) and task success."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from analysis.figures import arbitration_figure, mode_colors
from analysis.load import from_frames
from analysis.outcomes import success_comparisons, success_summary, wilson_interval
from analysis.report import write_report
from analysis.synthetic import synthetic_tables


def _three_modes(n: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A synthetic study whose aggressive runs are copied into a third mode, "yielding": as
    fast as aggressive when right, as timid's when wrong (plus noise), and every Easy&Wrong
    yielding run of the first half of the participants fails."""
    t = synthetic_tables(n, seed=3, rate_hz=10.0)
    trials, samples = t["trials"], t["samples"]
    agg = trials[trials["mode"] == "aggressive"].copy()
    timid = trials[trials["mode"] == "timid"].set_index(["participant", "task"])["duration_s"]
    rng = np.random.default_rng(1)
    offset = int(trials["trial_id"].max())
    key = list(zip(agg["participant"], agg["task"], strict=True))
    wrong = (agg["correctness"] == "wrong").to_numpy()
    base = np.where(wrong, timid.reindex(key).to_numpy(), agg["duration_s"].to_numpy())
    first_half = agg["participant"].isin([f"P{i + 1:02d}" for i in range(n // 2)])
    yielding = agg.assign(
        mode="yielding",
        trial_id=agg["trial_id"] + offset,
        duration_s=base + rng.normal(0, 0.5, len(agg)),
        outcome=np.where(first_half & (agg["task"] == "easy-wrong"), "timeout", "success"),
    )
    ys = samples[samples.trial_id.isin(agg["trial_id"])].assign(
        trial_id=lambda d: d["trial_id"] + offset
    )
    return (
        pd.concat([trials, yielding], ignore_index=True),
        pd.concat([samples, ys], ignore_index=True),
    )


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory):
    trials, samples = _three_modes(8)
    out = tmp_path_factory.mktemp("three")
    files = write_report(from_frames(trials, samples), out)
    return files, json.loads(files.results_json.read_text()), files.markdown.read_text()


def test_three_mode_report_models_every_factor_and_compares_every_mode_pair(report) -> None:
    files, _, md = report
    res = files.results
    assert res.timing is not None
    assert res.timing.factors == ("difficulty", "correctness", "mode")
    assert set(res.timing.levels["mode"]) == {"timid", "aggressive", "yielding"}
    rm = res.timing.rm.table.set_index("effect")
    assert (rm.loc["mode", "df1"], rm.loc["mode", "df2"]) == (2, 14)
    assert (rm.loc["difficulty:correctness:mode", "df1"]) == 2
    comp = res.timing.comparisons
    assert len(comp) == 4 * 3 and set(comp["m"]) == {3}  # 3 mode pairs in each of 4 tasks
    assert "differs from the paper" in " ".join(res.notes)
    # the yielding copy runs at aggressive's time when right and at timid's when wrong
    diff = comp.set_index("comparison")["mean_diff"]
    for task in ("easy-wrong", "hard-wrong"):
        assert diff[f"{task}: yielding - aggressive"] < -10
        assert abs(diff[f"{task}: yielding - timid"]) < 1
    for task in ("easy-right", "hard-right"):
        assert abs(diff[f"{task}: yielding - aggressive"]) < 1
        assert diff[f"{task}: yielding - timid"] < -2
    assert "| pairwise: modes within hard-wrong | hard-wrong: yielding - aggressive |" in md


def test_three_mode_report_has_success_per_condition(report) -> None:
    _, doc, md = report
    summary = pd.DataFrame(doc["success_summary"])
    assert len(summary) == 12
    ew = summary[(summary.task == "easy-wrong") & (summary["mode"] == "yielding")].iloc[0]
    assert (ew["trials"], ew["successes"]) == (8, 4)
    assert ew["ci_low"] < 0.5 < ew["ci_high"]
    comp = pd.DataFrame(doc["success_comparisons"])
    assert len(comp) == 12
    row = comp[(comp.task == "easy-wrong") & (comp.comparison.str.endswith("- yielding"))]
    assert set(row["second_only"]) == {0} and set(row["first_only"]) == {4}
    assert "## Task success by condition" in md
    assert "| easy-wrong | yielding | 8 | 0.50 [" in md


def test_three_modes_get_three_distinct_colours_in_the_figures(report) -> None:
    files, _, _ = report
    colours = mode_colors(["timid", "aggressive", "yielding", "other", "more"])
    assert len(set(colours.values())) == 5
    svg = next(p for p in files.figures if p.name == "fig8_time_preference.svg").read_text()
    for c in mode_colors(["timid", "aggressive", "yielding"]).values():
        assert c in svg


def test_wilson_interval_matches_the_closed_form() -> None:
    lo, hi = wilson_interval(4, 8)
    assert lo == pytest.approx(0.2152, abs=1e-4) and hi == pytest.approx(0.7848, abs=1e-4)
    assert wilson_interval(0, 10)[0] == 0.0 and wilson_interval(10, 10)[1] == 1.0
    assert all(np.isnan(wilson_interval(0, 0)))


def test_success_tables_follow_the_protocols_mode_order() -> None:
    trials = pd.DataFrame(
        {
            "participant": ["P1", "P1", "P2", "P2"],
            "task": ["t"] * 4,
            "mode": ["b", "a", "b", "a"],
            "phase": ["task"] * 4,
            "status": ["completed"] * 4,
            "outcome": ["success", "timeout", "success", "success"],
        }
    )
    s = success_summary(trials, modes=("a", "b"))
    assert list(s["mode"]) == ["a", "b"] and list(s["successes"]) == [1, 2]
    c = success_comparisons(trials, modes=("a", "b")).iloc[0]
    assert c["comparison"] == "a - b" and (c["first_only"], c["second_only"]) == (0, 1)
    assert c["difference"] == -0.5


def test_fig7_draws_a_stateful_kind_at_full_and_at_no_gain() -> None:
    fig = arbitration_figure(
        {
            "aggressive": {"kind": "aggressive", "threshold": 0.4, "alpha_high": 0.9},
            "yielding": {"kind": "yielding", "threshold": 0.4, "alpha_high": 0.9, "floor": 0.1},
        },
        rate_hz=100.0,
    )
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert set(lines) == {"aggressive", "yielding", "yielding, yielded"}
    c, full = lines["yielding"].get_data()
    _, low = lines["yielding, yielded"].get_data()
    assert np.allclose(full, lines["aggressive"].get_data()[1])
    assert np.allclose(low[c >= 0.4], 0.1) and np.allclose(low[c < 0.4], 0.0)
    assert lines["yielding, yielded"].get_linestyle() == "--"

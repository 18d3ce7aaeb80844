"""The report starts with the data at any n, and tests only where n allows: at n = 1 no
p-value, no r(df), no interval; at n = 4 the tests, with every interval defined. Knocks and the
data-quality listing from the events."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest

from analysis.descriptives import condition_descriptives, knocks_per_trial
from analysis.load import from_frames
from analysis.quality import data_quality
from analysis.report import write_report
from analysis.results import MIN_PARTICIPANTS
from analysis.synthetic import synthetic_tables

STATISTICS = re.compile(r"\bp [=<]|\bF\(|\br\(|\bt\(|\[\s*,|,\s*\]")
"""Anything inferential in a report's text: a p-value, F(, r(, t(, an interval with an end
missing."""


def _report(n: int, out: Path) -> tuple[str, dict]:
    t = synthetic_tables(n, seed=4, with_samples=False)
    files = write_report(from_frames(t["trials"], None, t["ratings"], t["events"]), out)
    return files.markdown.read_text(), json.loads(files.results_json.read_text())


def test_one_participant_gets_descriptives_and_no_statistics(tmp_path: Path) -> None:
    md, doc = _report(1, tmp_path / "r1")
    heads = re.findall(r"(?m)^## (.+)$", md)
    assert heads[:5] == [
        "Data",
        "Descriptives by condition",
        "Ratings by condition (Fig. 8)",
        "Data quality per participant",
        "Statistical tests: not computed",
    ]
    assert STATISTICS.search(md) is None, STATISTICS.search(md)
    assert f"none below {MIN_PARTICIPANTS}" in md
    assert doc["statistics"] == [] and "success_comparisons" not in doc
    assert "| easy-right | timid | 1 | 1 |" in md  # descriptives: n and runs per condition
    assert "(–)" in md  # an SD of one run is not defined, and says so
    assert (tmp_path / "r1" / "figures" / "fig8_ratings.png").stat().st_size > 10_000
    assert (tmp_path / "r1" / "figures" / "fig8_time_preference.png").exists()


def test_four_participants_get_the_tests_with_every_interval_defined(tmp_path: Path) -> None:
    md, doc = _report(4, tmp_path / "r4")
    assert "Statistical tests: not computed" not in md
    assert "Repeated-measures ANOVA (4 participants)" in md
    assert re.search(r"r\(14\) = ", md)  # 4 people x 4 tasks - 2
    assert re.search(r"\[\s*,|,\s*\]", md) is None
    assert any(s["analysis"] == "timing_rm" for s in doc["statistics"])


def test_descriptives_label_which_runs_each_mean_includes() -> None:
    t = synthetic_tables(3, seed=1, with_samples=False)["trials"]
    t.loc[t.index[5], ["success", "outcome", "duration_s"]] = [False, "timeout", 120.0]
    failed = t.loc[t.index[5]]
    same = t[(t.task == failed["task"]) & (t["mode"] == failed["mode"]) & (t.status == "completed")]
    dropped = same.index[same.index != t.index[5]][0]
    t.loc[dropped, ["success", "outcome"]] = [False, "dropped"]
    same = t.loc[same.index]
    d = condition_descriptives(from_frames(t)).set_index(["task", "mode"])
    row = d.loc[(failed["task"], failed["mode"])]
    assert row["runs"] == len(same) and row["successes"] == len(same) - 2
    assert row["timeouts"] == 1 and row["other_failures"] == {"dropped": 1}
    others = d.drop(index=(failed["task"], failed["mode"]))
    assert (others["timeouts"] == 0).all()
    assert row["time_all_mean"] == pytest.approx(same["duration_s"].mean())
    assert row["time_ok_mean"] == pytest.approx(same.loc[same.success, "duration_s"].mean())
    assert d.index[0] == ("practice", "none")


def test_knocks_come_from_the_events_or_the_column() -> None:
    trials = pd.DataFrame({"trial_id": [1, 2, 3]})
    samples = pd.DataFrame(
        {
            "trial_id": [1, 1, 2, 3],
            "events": [
                '["knocked_over:bottle"]',
                '["contact:hand:box", "knocked_over:box"]',
                "[]",
                '["knocked_over:mug", "pushed_off:mug"]',
            ],
        }
    )
    assert knocks_per_trial(trials, samples).to_dict() == {1: 2.0, 2: 0.0, 3: 1.0}
    with_column = trials.assign(knocks=[0, 4, 1])
    assert knocks_per_trial(with_column, samples).to_dict() == {1: 0.0, 2: 4.0, 3: 1.0}


def test_data_quality_counts_pauses_reloads_and_disconnections() -> None:
    t = synthetic_tables(2, seed=2, with_samples=False)
    ev = [
        ("P01", "participant_connected", "{}", "10:00"),
        ("P01", "pause", '{"cause": "tab_lost"}', "10:01"),
        ("P01", "participant_disconnected", "{}", "10:01"),
        ("P01", "participant_connected", "{}", "10:02"),
        ("P01", "pause", '{"cause": "experimenter"}', "10:03"),
        ("P01", "redo", "{}", "10:04"),
        ("P01", "finish", "{}", "10:05"),
        ("P01", "participant_disconnected", "{}", "10:06"),  # closing the tab at the end
        ("P02", "control_fault", "{}", "10:00"),
    ]
    events = pd.DataFrame(ev, columns=["participant", "kind", "detail", "at"])
    participants = pd.DataFrame(
        {
            "participant": ["P01", "P02", "P03"],
            "status": ["completed", "completed", "completed"],
            "included": [True, True, False],
            "excluded_because": [None, None, "declined data retention (answered 'No')"],
            "attention_checks": [1, 1, None],
            "attention_failures": [0, 1, None],
        }
    )
    tables = from_frames(t["trials"], None, t["ratings"], events, participants=participants)
    q = data_quality(tables).set_index("participant")
    p1 = q.loc["P01"]
    assert (p1["pauses (tab away)"], p1["pauses (experimenter)"]) == (1, 1)
    assert (p1["reloads"], p1["disconnections"], p1["task runs"]) == (1, 1, 8)
    assert q.loc["P02", "faults"] == 1 and q.loc["P02", "attention checks failed"] == "1 of 1"
    assert q.index[-1] == "P03" and q.loc["P03", "data"].startswith("left out: declined")
    assert q.loc["P03", "task runs"] == ""
    assert any("P03" in n for n in tables.notes)

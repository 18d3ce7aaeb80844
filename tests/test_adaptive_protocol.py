"""protocols/adaptive.toml: three modes over the paper's four tasks, balanced, blinded, runnable."""

from __future__ import annotations

import json
from collections import Counter
from itertools import pairwise, permutations
from pathlib import Path

import pytest

from analysis.load import load_tables
from analysis.report import write_report
from study.protocol import load_protocol
from study.schedule import Design, schedule
from study.simulated.runner import simulate

ROOT = Path(__file__).resolve().parents[1]
ADAPTIVE = ROOT / "protocols" / "adaptive.toml"


@pytest.fixture(scope="module")
def adaptive():
    return load_protocol(ADAPTIVE)


def test_adaptive_declares_three_modes_with_the_yielding_kind(adaptive) -> None:
    assert adaptive.mode_names == ("timid", "aggressive", "yielding")
    assert adaptive.factors["difficulty"] == ("easy", "hard")
    assert adaptive.factors["correctness"] == ("right", "wrong")
    arb = {m.name: dict(m.arbitration) for m in adaptive.modes}
    assert arb["yielding"]["kind"] == "yielding"
    # yielding starts from aggressive's own curve: only the yielding differs
    for key in ("threshold", "alpha_high"):
        assert arb["yielding"][key] == arb["aggressive"][key]
    assert all(m.intent == "none" for m in adaptive.modes)
    assert adaptive.questionnaire.after_task == ()  # a preference needs exactly two runs
    for word in ("timid", "aggressive", "yielding", "yield"):
        for text in (
            adaptive.consent_text,
            adaptive.debrief_text,
            adaptive.describe_trial("easy-wrong"),
        ):
            assert word not in text.lower()


def test_a_cycle_of_24_balances_the_twelve_condition_order(adaptive) -> None:
    design = Design.from_protocol(adaptive)
    assert design.cycle == 4 * 6 and design.trials_per_participant == 12
    assert adaptive.study.participants % design.cycle == 0
    trials = schedule(design, participants=design.cycle)
    by_participant: dict[str, list] = {}
    for t in trials:
        by_participant.setdefault(t.participant, []).append(t)
    conditions = {(t, m) for t in adaptive.task_names for m in adaptive.mode_names}
    for rows in by_participant.values():  # each participant: every condition once
        assert {(t.task, t.mode) for t in rows} == conditions and len(rows) == 12
    # every condition in each of the 12 positions equally often (24 / 12 = 2)
    at = Counter((t.task, t.mode, t.position) for t in trials)
    assert set(at.values()) == {2} and len(at) == 12 * 12
    # tasks: each in each slot equally often, first-order carry-over balanced
    orders = [list(dict.fromkeys(t.task for t in rows)) for rows in by_participant.values()]
    for slot in range(4):
        assert set(Counter(o[slot] for o in orders).values()) == {6}
    carry = Counter(p for o in orders for p in pairwise(o))
    assert set(carry.values()) == {6} and len(carry) == 12
    # modes within each task: each in each run equally often, carry-over balanced
    for task in adaptive.task_names:
        runs = Counter((t.mode, t.run) for t in trials if t.task == task)
        assert set(runs.values()) == {8} and len(runs) == 9
        seqs = [[t.mode for t in rows if t.task == task] for rows in by_participant.values()]
        mode_carry = Counter(p for s in seqs for p in pairwise(s))
        assert set(mode_carry) == set(permutations(adaptive.mode_names, 2))
        assert set(mode_carry.values()) == {8}


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory):
    """Three simulated participants through protocols/adaptive.toml, and their report."""
    d = tmp_path_factory.mktemp("adaptive")
    db = d / "study.db"
    simulate(protocol_path=ADAPTIVE, db=db, participants=3, seed=5, progress=False)
    tables = load_tables(db=db)
    files = write_report(tables, d / "report")
    return tables, files, json.loads(files.results_json.read_text())


def test_simulated_adaptive_store_reports_all_three_modes(simulated) -> None:
    tables, files, doc = simulated
    done = tables.trials[tables.trials.phase == "task"]
    assert Counter(done["mode"]) == {"timid": 12, "aggressive": 12, "yielding": 12}
    res = files.results
    assert res.timing is not None
    assert res.timing.levels["mode"] == ("timid", "aggressive", "yielding")
    rm = res.timing.rm.table.set_index("effect")
    assert (rm.loc["mode", "df1"], rm.loc["mode", "df2"]) == (2, 4)
    assert len(res.timing.comparisons) == 12
    assert len(doc["success_summary"]) == 12 and len(doc["success_comparisons"]) == 12
    md = files.markdown.read_text()
    assert "yielding" in md and "Task success by condition" in md
    fig7 = next(p for p in files.figures if p.name == "fig7_arbitration.svg")
    assert fig7.exists()
    # the yielding runs logged the motion agreement that drives them, and gave way when wrong:
    # less assistance than aggressive's over the Wrong runs
    s = tables.samples.merge(done[["trial_id", "mode", "correctness"]], on="trial_id")
    assert s.loc[s["mode"] == "yielding", "motion_agreement"].notna().mean() > 0.9
    wrong = s[s["correctness"] == "wrong"].groupby("mode")["alpha"].mean()
    assert wrong["yielding"] < wrong["aggressive"] - 0.1

"""``python -m study simulate`` end to end: simulated participants through the real session
engine, control loop and store (MuJoCo physics, headless).

The protocol is the study's own with a shorter time limit (20 s instead of 120 s) so that a
trial the simulated user cannot finish ends quickly; everything else is unchanged.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from study.cli import simulate as simulate_cli
from study.protocol import load_protocol
from study.store import Store

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory, short_protocol: Path) -> tuple[dict, Path]:
    db = tmp_path_factory.mktemp("store") / "sim.db"
    parser = argparse.ArgumentParser()
    simulate_cli.add_arguments(parser)
    args = parser.parse_args(
        [
            "--protocol",
            str(short_protocol),
            "--participants",
            "1",
            "--db",
            str(db),
            "--seed",
            "3",
            "--no-progress",
        ]
    )
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = simulate_cli.main(args)
    lines = out.getvalue().strip().splitlines()
    summary = json.loads(lines[-1])
    assert code == 0, summary
    return summary, db


def test_summary_line(simulated: tuple[dict, Path]) -> None:
    summary, _ = simulated
    assert summary["participants"] == 1
    assert summary["trials"] == 11  # 3 training runs + 4 tasks x 2 modes
    assert summary["ratings"] == 3 + 8 * 3 + 4
    assert summary["wall_s"] > 0
    assert summary["errors"] == []


def test_store_holds_a_completed_session(
    simulated: tuple[dict, Path], short_protocol: Path
) -> None:
    _, db = simulated
    protocol = load_protocol(short_protocol)
    with Store.open_readonly(db) as store:
        (session,) = store.sessions()
        assert session.status == "completed"
        assert session.participant == "sim3-001"
        trials = store.trials()
        assert [t.phase for t in trials].count("training") == protocol.training.runs
        task_trials = [t for t in trials if t.phase == "task"]
        assert len(task_trials) == 8
        assert all(t.status == "completed" for t in trials)
        conditions = {(t.task, t.mode) for t in task_trials}
        assert len(conditions) == 8
        for t in trials:
            assert t.outcome in ("success", "timeout", "wrong_object")  # no accident ends a run
            assert store.sample_count(t.trial_id) == t.ticks > 0
            assert t.duration_s is not None and 0 < t.duration_s <= 20.0 + 1e-6
        # the simulated user picks the object up where the task is feasible
        assert sum(t.outcome == "success" for t in trials) >= 6
        ratings = store.ratings()
        assert {r.item for r in ratings} == {"helpful", "matched", "teammate", "preference"}
        assert all(1 <= r.value <= 7 for r in ratings)
        assert sum(r.item == "preference" for r in ratings) == 4
        assert store.demographics("sim3-001")["simulated"] is True
        kinds = [e.kind for e in store.events()]
        assert "simulated_participant" in kinds and "finish" in kinds


def test_same_participant_cannot_be_simulated_twice(
    simulated: tuple[dict, Path], short_protocol: Path
) -> None:
    _, db = simulated
    from study.simulated import SimulationRunError
    from study.simulated.runner import simulate

    with pytest.raises(SimulationRunError, match=r"sim3-001 is already in .*--first 1"):
        simulate(protocol_path=short_protocol, db=db, participants=1, seed=3, progress=False)


@pytest.mark.parametrize("bad", [{"seed": -1}, {"first": -2}, {"seed": 1.5}])
def test_bad_seed_or_first_is_refused_before_a_store_exists(
    tmp_path: Path, short_protocol: Path, bad: dict
) -> None:
    from study.simulated import SimulationRunError
    from study.simulated.runner import simulate

    options = {"seed": 1, **bad}
    name = next(iter(bad))
    with pytest.raises(SimulationRunError, match=rf"{name} must be an integer >= 0"):
        simulate(
            protocol_path=short_protocol,
            db=tmp_path / "sim.db",
            participants=1,
            progress=False,
            **options,
        )
    assert not (tmp_path / "sim.db").exists()


def test_the_report_shows_decoy_share_and_contacts(simulated: tuple[dict, Path]) -> None:
    from analysis.contact_summary import contact_section, contact_summary
    from analysis.decoy_share import decoy_section, decoy_shares
    from analysis.load import load_tables

    _, db = simulated
    tables = load_tables(db=db)
    shares = decoy_shares(tables.trials, tables.samples)
    assert len(shares) == 4  # two Wrong tasks x two modes
    decoy = decoy_section(tables)
    assert decoy is not None
    assert f"median {shares['decoy_share'].median():.2f} over 4 trials" in decoy.paragraphs[0]
    summary = contact_summary(tables.trials)
    assert summary["trials"].sum() == 8 and (summary["mean touches"] >= 0).all()
    assert contact_section(tables) is not None

"""Prediction replay against the paper's closed forms, and the predict command."""

from __future__ import annotations

import dataclasses
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.__main__ import main as analysis_main
from analysis.load import from_frames, task_cells
from analysis.prediction_eval import (
    PREDICTORS,
    evaluate_predictions,
    first_lasting_correct,
    goal_moves,
    make_predictor,
    prediction_anova,
    protocol_predictors,
    replay,
    trial_trajectories,
)
from analysis.protocol_info import load_protocol_info
from analysis.synthetic import synthetic_tables
from app.teleop import GizmoInput
from app.trial import Trial
from app.trial.events import encode_events
from study.protocol import trial_config_from_protocol
from tests.support.cli import Ran, run_main

ROOT = Path(__file__).resolve().parents[1]
GOALS = np.array([[0.45, -0.05, 0.05], [0.60, 0.25, 0.08]])  # box (near), bottle (target)


def _curved(n: int = 200, seed: int = 0) -> np.ndarray:
    """From a start near the box over toward it, then on to the bottle, with noise."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, n)[:, None]
    start, via = np.array([0.35, 0.0, 0.3]), np.array([0.47, 0.02, 0.12])
    path = np.where(s < 0.5, start + (via - start) * (2 * s), via + (GOALS[1] - via) * (2 * s - 1))
    return path + rng.normal(0, 0.004, path.shape)


def test_first_lasting_correct() -> None:
    assert first_lasting_correct(np.array([False, True, False, True, True])) == 3
    assert first_lasting_correct(np.array([True, True])) == 0
    assert first_lasting_correct(np.array([True, False])) is None
    assert first_lasting_correct(np.array([], dtype=bool)) is None


def test_amnesic_replay_is_the_nearest_goal() -> None:
    traj = _curved()
    rep = replay(GOALS, traj, make_predictor(PREDICTORS["amnesic"], GOALS), target=1)
    nearest = np.linalg.norm(traj[:, None] - GOALS[None], axis=2).argmin(axis=1)
    np.testing.assert_array_equal(rep.predicted, nearest)
    assert rep.correct is not None
    assert rep.correct.mean() == pytest.approx((nearest == 1).mean())
    np.testing.assert_allclose(rep.probabilities.sum(axis=1), 1.0)


def test_memory_replay_follows_eq9_with_squared_velocity() -> None:
    # Eq. 9 with C = sum ||dx||^2 and a fixed horizon scores goals by ||S-G||^2 - ||U-G||^2:
    # the goal the user has made the most (squared-distance) progress toward.
    traj = _curved(seed=2)
    rep = replay(GOALS, traj, make_predictor(PREDICTORS["memory"], GOALS), target=1)
    s = traj[0]
    score = ((s - GOALS) ** 2).sum(axis=1)[None] - ((traj[:, None] - GOALS[None]) ** 2).sum(axis=2)
    expect = score.argmax(axis=1)
    decided = np.abs(score[:, 0] - score[:, 1]) > 1e-12
    np.testing.assert_array_equal(rep.predicted[decided], expect[decided])
    amnesic = replay(GOALS, traj, make_predictor(PREDICTORS["amnesic"], GOALS), target=1)
    assert rep.correct.mean() > amnesic.correct.mean()  # the paper's finding on this path


def test_evaluation_and_four_factor_anova(tmp_path: Path) -> None:
    d = synthetic_tables(8, seed=3, rate_hz=10.0)
    cells, _ = task_cells(from_frames(d["trials"]).trials)
    evals, notes = evaluate_predictions(cells, d["samples"].iloc[::-1])  # order must not matter
    assert notes == ()
    assert len(evals) == 128 and set(evals["predictor"]) == {"amnesic", "memory"}
    one = evals.iloc[0]
    smp = d["samples"][d["samples"].trial_id == one["trial_id"]]
    assert one["n_ticks"] == len(smp)
    res = prediction_anova(evals)
    assert res.df_resid == 112 and set(res.table["df2"]) == {112}
    assert len(res.table) == 15  # 4 main effects, 6 + 4 + 1 interactions
    # samples missing for one trial: a note, not a failure
    partial = d["samples"][d["samples"].trial_id != one["trial_id"]]
    evals2, notes2 = evaluate_predictions(cells, partial)
    assert len(evals2) == 126 and str(one["trial_id"]) in notes2[0]


def _predict(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "analysis", "predict", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_predict_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The first call is a new ``python -m analysis predict`` process, as a user runs it; the
    others call the same command line's ``main`` here (no start-up and imports each)."""

    def predict(*args: str) -> Ran:
        return run_main(analysis_main, ["predict", *args], capsys)

    goals = tmp_path / "goals.csv"
    pd.DataFrame(
        {"goal": ["box", "bottle"], "x": GOALS[:, 0], "y": GOALS[:, 1], "z": GOALS[:, 2]}
    ).to_csv(goals, index=False)
    traj = _curved(60)
    tr = tmp_path / "traj.csv"
    pd.DataFrame(
        {"t": np.arange(60) / 10, "x": traj[:, 0], "y": traj[:, 1], "z": traj[:, 2]}
    ).to_csv(tr, index=False)
    out = _predict("--goals", str(goals), "--trajectory", str(tr), "--method", "amnesic")
    assert out.returncode == 0, out.stderr
    df = pd.read_csv(io.StringIO(out.stdout))
    assert list(df.columns) == ["t", "p_box", "p_bottle", "predicted", "confidence"]
    nearest = np.where(
        np.linalg.norm(traj - GOALS[1], axis=1) < np.linalg.norm(traj - GOALS[0], axis=1),
        "bottle",
        "box",
    )
    assert (df["predicted"].to_numpy() == nearest).all()
    assert np.allclose(df["confidence"], df[["p_box", "p_bottle"]].max(axis=1), atol=1e-5)
    mem = predict(
        "--goals", str(goals), "--trajectory", str(tr), "--method", "memory", "--cost", "length"
    )
    assert mem.returncode == 0 and mem.stdout.count("\n") == 61
    # the protocol format's cost name and the short one are the same cost
    named = [
        predict(
            "--goals", str(goals), "--trajectory", str(tr), "--method", "memory", "--cost", cost
        )
        for cost in ("squared_velocity", "sqvel")
    ]
    assert named[0].returncode == 0 and named[0].stdout == named[1].stdout != mem.stdout
    # configuration-space columns q1..qn work the same way
    pd.DataFrame({"goal": ["a", "b"], "q1": [0, 1], "q2": [0, 1]}).to_csv(goals, index=False)
    pd.DataFrame({"t": [0, 1, 2], "q1": [0.1, 0.6, 0.9], "q2": [0, 0.5, 1]}).to_csv(tr, index=False)
    q = predict("--goals", str(goals), "--trajectory", str(tr), "--method", "amnesic")
    assert q.returncode == 0 and list(pd.read_csv(io.StringIO(q.stdout))["predicted"]) == [
        "a",
        "b",
        "b",
    ]
    # bad input: clear message, exit 2, no traceback
    pd.DataFrame({"t": [0, 1], "q1": ["x", 0.3], "q2": [0, 1]}).to_csv(tr, index=False)
    bad = predict("--goals", str(goals), "--trajectory", str(tr), "--method", "memory")
    assert bad.returncode == 2 and "must be numeric" in bad.stderr
    assert "Traceback" not in bad.stderr
    pd.DataFrame({"t": [0, 1], "x": [0.1, 0.2]}).to_csv(tr, index=False)
    cols = predict("--goals", str(goals), "--trajectory", str(tr), "--method", "memory")
    assert cols.returncode == 2 and "q1" in cols.stderr


def test_parallel_replay_gives_the_same_table() -> None:
    d = synthetic_tables(2, seed=5, rate_hz=10.0)
    cells, _ = task_cells(from_frames(d["trials"]).trials)
    serial, _ = evaluate_predictions(cells, d["samples"], workers=1)
    parallel, _ = evaluate_predictions(cells, d["samples"], workers=2)
    pd.testing.assert_frame_equal(serial, parallel)


def test_replay_moves_goals_where_the_robot_moved_them(protocol_path: Path) -> None:
    """A trial whose box was nudged: replaying its samples reproduces the robot's own amnesic
    prediction tick by tick only when the logged goal moves are applied."""
    cfg = trial_config_from_protocol(protocol_path, "easy-wrong", "timid")
    gizmo = GizmoInput()
    trial = Trial(dataclasses.replace(cfg, time_limit_s=30), gizmo)
    k = trial.scene.goals.index("box")
    trial.tick()
    trial.sim.set_grip_contacts(True, only=[k])
    addr = trial.scene.object_qpos_addr[k]
    trial.sim.data.qpos[addr : addr + 2] += (-0.05, 0.04)
    gizmo.set_target(trial.scene.goals.positions[k] + (-0.05, 0.04, 0.05))  # to the box, moved
    for _ in range(80):
        trial.tick()
    recs = trial.records
    samples = pd.DataFrame(
        {
            "trial_id": 1,
            "tick": [r.tick for r in recs],
            "t": [r.t for r in recs],
            "target_x": [r.user_target[0] for r in recs],
            "target_y": [r.user_target[1] for r in recs],
            "target_z": [r.user_target[2] for r in recs],
            "events": [encode_events(r.events) for r in recs],
        }
    )
    _, xyz, moved = trial_trajectories(samples)[1]
    names = list(trial.scene.goals.names)
    moves = goal_moves(moved, names, 1)
    assert moves is not None and set(moves.goals) == {k}
    online = np.array([r.probabilities for r in recs])
    pts = np.asarray(trial.scene.goals.positions)
    with_moves = replay(pts, xyz, make_predictor(PREDICTORS["amnesic"], pts), moves=moves)
    without = replay(pts, xyz, make_predictor(PREDICTORS["amnesic"], pts))
    np.testing.assert_allclose(with_moves.probabilities, online, atol=1e-4)
    assert np.abs(without.probabilities - online).max() > 1e-2


def test_protocol_predictors_take_the_protocols_tables() -> None:
    paper, how = protocol_predictors(
        load_protocol_info(ROOT / "protocols" / "dragan2013.toml").prediction
    )
    assert paper == PREDICTORS  # [prediction.wrong] is amnesic at 0.05; no memory table
    assert "[prediction.wrong]" in how[0].source and "paper's default" in how[1].source
    m3, how = protocol_predictors(
        load_protocol_info(ROOT / "protocols" / "memory3.toml").prediction
    )
    assert m3["memory"] == {"kind": "memory", "cost": "length", "rationality": 30.0}
    assert how[1].describe() == (
        "memory: cost length, rationality 30 (the protocol's [prediction.memory])"
    )
    joint, how = protocol_predictors(
        {
            "m": {"kind": "memory", "space": "configuration"},
            "a": {"kind": "amnesic", "temperature": 0.1},
        }
    )
    assert joint["memory"] == PREDICTORS["memory"] and "configuration space" in how[1].source
    assert joint["amnesic"] == {"kind": "amnesic", "temperature": 0.1}

"""Blending: GoalSet, PolicyBlender per tick, factories from protocol tables, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.blending import (
    Aggressive,
    AmnesicPredictor,
    BlendRecord,
    ConfigError,
    DistanceHinge,
    GoalSet,
    InvalidInputError,
    MemoryPredictor,
    NoAssistance,
    OraclePredictor,
    PolicyBlender,
    StraightLinePolicy,
    Timid,
    arbitration_from_config,
    confidence_from_config,
    policy_from_config,
    predictor_from_config,
)


def two_goals() -> GoalSet:
    return GoalSet(
        ["near", "far"],
        positions=[[0.4, 0.0, 0.1], [0.8, 0.0, 0.1]],
        configurations=[[0.1] * 7, [0.5] * 7],
    )


def make_blender(goals: GoalSet, **kw) -> PolicyBlender:
    args = dict(
        goals=goals,
        predictor=AmnesicPredictor(goals.positions, temperature=0.05),
        confidence=DistanceHinge(0.4),
        arbitration=Aggressive(0.4, 0.9),
        policy=StraightLinePolicy(0.01),
        space="workspace",
    )
    args.update(kw)
    return PolicyBlender(**args)


def test_goalset_index_len_points() -> None:
    g = two_goals()
    assert len(g) == 2 and g.index("far") == 1
    np.testing.assert_array_equal(g.points("configuration")[1], [0.5] * 7)
    with pytest.raises(InvalidInputError, match="no goal called 'x'"):
        g.index("x")
    with pytest.raises(InvalidInputError, match="empty"):
        GoalSet([], np.zeros((0, 3)))
    with pytest.raises(InvalidInputError, match="positions: expected 2 rows"):
        GoalSet(["a", "b"], [[0, 0, 0]])
    with pytest.raises(InvalidInputError, match="positions: contains NaN"):
        GoalSet(["a"], [[0, np.nan, 0]])
    with pytest.raises(InvalidInputError, match="distinct"):
        GoalSet(["a", "a"], [[0, 0, 0], [1, 0, 0]])
    with pytest.raises(InvalidInputError, match="unit norm"):
        GoalSet(["a"], [[0, 0, 0]], orientations=[[1, 1, 0, 0]])
    with pytest.raises(InvalidInputError, match="has none"):
        GoalSet(["a"], [[0, 0, 0]]).points("configuration")


def test_step_blends_hand_computed() -> None:
    g = two_goals()
    b = make_blender(g)
    b.reset([0.0, 0.0, 0.1])
    q = np.zeros(7)
    u = np.full(7, 0.002)
    # x at 0.1 m from "near": d = 0.1, conf = 1 - 0.1/0.4 = 0.75 >= 0.4 -> alpha = 0.9
    rec = b.step(q, u, x=[0.3, 0.0, 0.1])
    assert isinstance(rec, BlendRecord)
    assert rec.predicted == 0
    assert rec.distance == pytest.approx(0.1)
    assert rec.confidence == pytest.approx(0.75)
    assert rec.alpha == pytest.approx(0.9)
    # P: step of 0.01 along (0.1,...,0.1)/||.|| from 0 -> 0.01/sqrt(7) per joint
    np.testing.assert_allclose(rec.P, np.full(7, 0.01 / math.sqrt(7)))
    np.testing.assert_allclose(rec.command, 0.1 * u + 0.9 * rec.P)
    # softmin over d = (0.1, 0.5), T = 0.05: p_near = 1 / (1 + exp(-8))
    assert rec.probabilities[0] == pytest.approx(1 / (1 + math.exp(-8)))
    assert rec.agreement == pytest.approx(1.0)


def test_agreement_is_negative_when_user_opposes_robot() -> None:
    b = make_blender(two_goals())
    b.reset([0.0, 0.0, 0.1])
    rec = b.step(np.zeros(7), np.full(7, -0.002), x=[0.3, 0.0, 0.1])
    assert rec.agreement == pytest.approx(-1.0)
    rec0 = b.step(np.zeros(7), np.zeros(7), x=[0.3, 0.0, 0.1])
    assert rec0.agreement == 0.0


def test_feature_maps_u_to_predictor_space() -> None:
    g = two_goals()
    calls = []

    def fk(q: np.ndarray) -> np.ndarray:
        calls.append(q.copy())
        return np.array([q[0], 0.0, 0.1])

    b = make_blender(g, feature=fk)
    b.reset([0.0, 0.0, 0.1])
    rec = b.step(np.zeros(7), np.full(7, 0.75))
    assert rec.predicted == 1 and rec.distance == pytest.approx(0.05)
    assert len(calls) == 1


def test_no_assistance_passes_user_through() -> None:
    b = make_blender(two_goals(), arbitration=NoAssistance())
    b.reset([0.0, 0.0, 0.1])
    u = np.linspace(0, 0.01, 7)
    rec = b.step(np.zeros(7), u, x=[0.39, 0.0, 0.1])
    assert rec.alpha == 0.0
    np.testing.assert_array_equal(rec.command, u)


@pytest.mark.parametrize(
    ("q", "u", "x", "match"),
    [
        ([np.nan] + [0.0] * 6, [0.0] * 7, [0, 0, 0], "Q: contains NaN"),
        ([0.0] * 7, [np.inf] + [0.0] * 6, [0, 0, 0], "U: contains NaN or infinite"),
        ([0.0] * 7, [0.0] * 7, [0, np.nan, 0], "x: contains NaN"),
        ([0.0] * 6, [0.0] * 7, [0, 0, 0], r"Q: expected shape \(7,\)"),
        ([0.0] * 7, [0.0] * 8, [0, 0, 0], r"U: expected shape \(7,\)"),
        ([0.0] * 7, [0.0] * 7, [0, 0], r"x: expected shape \(3,\)"),
    ],
)
def test_step_rejects_bad_input(q, u, x, match) -> None:
    b = make_blender(two_goals())
    b.reset([0.0, 0.0, 0.1])
    with pytest.raises(InvalidInputError, match=match):
        b.step(q, u, x=x)


def test_step_before_reset_and_bad_start() -> None:
    b = make_blender(two_goals())
    with pytest.raises(InvalidInputError, match="reset"):
        b.step(np.zeros(7), np.zeros(7), x=[0, 0, 0])
    with pytest.raises(InvalidInputError, match="start_x"):
        b.reset([0.0, np.nan, 0.0])


def test_blender_rejects_mismatched_predictor() -> None:
    g = two_goals()
    with pytest.raises(InvalidInputError, match="predicts over 3 goals"):
        make_blender(g, predictor=AmnesicPredictor(np.zeros((3, 3))))
    with pytest.raises(InvalidInputError, match="works in 7-D"):
        make_blender(g, predictor=AmnesicPredictor(g.configurations))


def test_goals_change_at_run_time_memory_keeps_history() -> None:
    g = two_goals()
    pred = MemoryPredictor(g.positions, rationality=10.0)
    b = make_blender(g, predictor=pred)
    b.reset([0.0, 0.0, 0.1])
    b.step(np.zeros(7), np.zeros(7), x=[0.2, 0.0, 0.1])
    cost_before = pred.path_cost
    g3 = GoalSet(
        ["a", "b", "c"],
        positions=[[0.4, 0.0, 0.1], [0.8, 0.0, 0.1], [0.0, 0.5, 0.1]],
        configurations=[[0.1] * 7, [0.5] * 7, [-0.5] * 7],
    )
    b.set_goals(g3)
    assert pred.path_cost == cost_before
    rec = b.step(np.zeros(7), np.zeros(7), x=[0.2, 0.0, 0.1])
    assert rec.probabilities.shape == (3,)
    assert rec.probabilities.sum() == pytest.approx(1.0)
    # progress toward c is negative (moved away from it): least likely
    assert rec.probabilities.argmin() == 2


def test_oracle_in_blender() -> None:
    g = two_goals()
    b = make_blender(g, predictor=OraclePredictor(2, goal=1))
    b.reset([0.0, 0.0, 0.1])
    rec = b.step(np.zeros(7), np.zeros(7), x=[0.4, 0.0, 0.1])
    assert rec.predicted == 1
    np.testing.assert_array_equal(rec.probabilities, [0.0, 1.0])
    assert rec.distance == pytest.approx(0.4)


# --- factories --------------------------------------------------------------------------


def test_factories_build_the_protocol_examples() -> None:
    g = two_goals()
    timid = arbitration_from_config({"kind": "timid", "alpha_max": 0.5, "saturation": 0.7})
    assert isinstance(timid, Timid) and timid(0.35) == pytest.approx(0.25)
    aggr = arbitration_from_config({"kind": "aggressive", "threshold": 0.4, "alpha_high": 0.9})
    assert aggr(0.39) == 0.0 and aggr(0.4) == 0.9
    assert arbitration_from_config({"kind": "none"})(1.0) == 0.0
    pw = arbitration_from_config({"kind": "piecewise_linear", "points": [[0, 0], [1, 0.5]]})
    assert pw(0.5) == pytest.approx(0.25)
    lin = arbitration_from_config({"kind": "linear", "alpha_min": 0.2, "alpha_max": 0.6})
    assert lin(0.5) == pytest.approx(0.4)
    am = predictor_from_config(
        {"kind": "amnesic", "space": "workspace", "temperature": 0.05}, points=g
    )
    assert isinstance(am, AmnesicPredictor) and am.points.shape == (2, 3)
    cs = predictor_from_config({"kind": "amnesic", "space": "configuration"}, points=g)
    assert cs.points.shape == (2, 7)
    orc = predictor_from_config({"kind": "oracle"}, points=g, target="far")
    assert orc.update(None).index == 1
    mem = predictor_from_config({"kind": "memory", "cost": "length", "rationality": 5}, points=g)
    assert isinstance(mem, MemoryPredictor) and mem.rationality == 5.0
    sq = predictor_from_config({"kind": "memory", "cost": "squared_velocity", "steps": 4}, points=g)
    assert sq.cost.steps == 4
    d = confidence_from_config({"kind": "distance", "D": 0.4})
    assert d(None, 0.1) == pytest.approx(0.75)
    pol = policy_from_config({"kind": "straight_line", "max_speed": 1.0}, rate_hz=50)
    assert pol.max_step == pytest.approx(0.02)


@pytest.mark.parametrize(
    ("factory", "cfg", "message"),
    [
        (
            arbitration_from_config,
            {"kind": "timid", "alpha_max": 1.5},
            "modes.x.alpha_max: must be in (0, 1), got 1.5",
        ),
        (
            arbitration_from_config,
            {"kind": "aggressive", "threshold": -0.1},
            "modes.x.threshold: must be in [0, 1], got -0.1",
        ),
        (arbitration_from_config, {"kind": "aggressive"}, "modes.x.threshold: missing"),
        (
            arbitration_from_config,
            {"kind": "timid", "alpha_max": 0.5, "sat": 1},
            "modes.x.sat: unknown key",
        ),
        (arbitration_from_config, {"kind": "bold"}, "modes.x.kind: 'bold' is not one of timid"),
        (arbitration_from_config, {"alpha_max": 0.5}, "modes.x.kind: missing"),
        (
            arbitration_from_config,
            {"kind": "piecewise_linear", "points": [[0, 0.5], [1, 0.2]]},
            "modes.x.points: alpha must not decrease",
        ),
        (
            arbitration_from_config,
            {"kind": "timid", "alpha_max": "big"},
            "modes.x.alpha_max: expected a number",
        ),
        (
            confidence_from_config,
            {"kind": "distance", "D": -0.4},
            "modes.x.D: must be in (0, 5], got -0.4",
        ),
        (confidence_from_config, {"kind": "distance"}, "modes.x.D: missing"),
        (
            predictor_from_config,
            {"kind": "amnesic", "temperature": 0},
            "modes.x.temperature: must be > 0, got 0",
        ),
        (
            predictor_from_config,
            {"kind": "memory", "cost": "jerk"},
            "modes.x.cost: 'jerk' is not one of 'length', 'squared_velocity'",
        ),
        (
            predictor_from_config,
            {"kind": "memory", "rationality": float("nan")},
            "modes.x.rationality: must be finite",
        ),
        (
            predictor_from_config,
            {"kind": "memory", "prior": [1, -1]},
            "modes.x.prior: weights must be >= 0",
        ),
        (
            predictor_from_config,
            {"kind": "memory", "prior": [1, 1, 1]},
            "modes.x.prior: expected last dimension 2",
        ),
        (predictor_from_config, {"kind": "oracle"}, "modes.x.goal: oracle prediction needs"),
        (predictor_from_config, {"kind": "oracle", "goal": 5}, "modes.x.goal: must be an index"),
        (
            predictor_from_config,
            {"kind": "oracle", "goal": "nope"},
            "modes.x.goal: no goal called 'nope'",
        ),
        (
            predictor_from_config,
            {"kind": "amnesic", "space": "joint"},
            "modes.x.space: 'joint' is not one of",
        ),
        (predictor_from_config, {"kind": "laplace", "cost": "length"}, "modes.x.cost: eq. 8"),
        (
            policy_from_config,
            {"kind": "straight_line", "max_speed": 0},
            "modes.x.max_speed: must be in (0, 10], got 0",
        ),
        (
            policy_from_config,
            {"kind": "workspace_line", "max_speed": 0.2},
            "modes.x.kind: 'workspace_line' needs fk=",
        ),
    ],
)
def test_factory_errors_name_the_key_path(factory, cfg, message) -> None:
    kwargs = {"where": "modes.x"}
    if factory is predictor_from_config:
        kwargs["points"] = two_goals()
    if factory is policy_from_config:
        kwargs["rate_hz"] = 30
    with pytest.raises(ConfigError) as info:
        factory(cfg, **kwargs)
    assert str(info.value).startswith(message), str(info.value)


def test_absurd_magnitudes_are_rejected_by_name() -> None:
    b = make_blender(two_goals())
    b.reset([0.0, 0.0, 0.1])
    with pytest.raises(InvalidInputError, match="U: values of magnitude"):
        b.step(np.zeros(7), np.full(7, 1e200), x=[0.0, 0.0, 0.0])


def test_configuration_policy_needs_goal_configurations() -> None:
    g = GoalSet(["a", "b"], [[0.4, 0, 0.1], [0.8, 0, 0.1]])
    with pytest.raises(InvalidInputError, match="StraightLinePolicy steers toward goal conf"):
        make_blender(g)


def test_workspace_policy_runs_without_goal_configurations() -> None:
    from app.blending import WorkspaceLinePolicy

    g = GoalSet(["a", "b"], [[0.4, 0, 0.1], [0.8, 0, 0.1]])
    a = np.hstack([np.eye(3), np.zeros((3, 4))])
    pol = WorkspaceLinePolicy(fk=lambda q: a @ q, jacobian=lambda q: a, max_step=0.01, damping=0.0)
    b = make_blender(g, policy=pol, feature=lambda q: a @ q)
    b.reset([0.0, 0.0, 0.1])
    q = np.array([0.3, 0.0, 0.1, 0, 0, 0, 0])
    rec = b.step(q, q)
    assert rec.predicted == 0
    np.testing.assert_allclose(rec.P[:3] - q[:3], [0.01, 0.0, 0.0], atol=1e-12)

"""Stateful arbitration (yielding, user_confidence) and the online rationality estimate."""

from __future__ import annotations

import copy
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.blending import (
    GoalSet,
    MemoryPredictor,
    PolicyBlender,
    ProbabilityConfidence,
    StraightLinePolicy,
    arbitration_from_config,
    is_adversarial,
    predictor_from_config,
)
from app.blending.adaptive import TickSignals, UserConfidence, Yielding
from app.blending.prediction.rationality import RationalityEstimator

SETTINGS = settings(max_examples=60, deadline=None)
RATE = 50.0
unit = st.floats(0.0, 1.0, allow_nan=False)
cosine = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def yieldings(draw) -> Yielding:
    return Yielding(
        threshold=draw(unit),
        alpha_high=draw(st.floats(0.05, 1.0)),
        agree_below=draw(st.floats(-0.9, 0.9)),
        window_s=draw(st.floats(0.0, 1.0)),
        floor=draw(unit),
        fall_s=draw(st.floats(0.02, 1.0)),
        recover_s=draw(st.floats(0.05, 5.0)),
        rate_hz=RATE,
    )


def signals(c: float, agreement: float) -> TickSignals:
    return TickSignals(c, 0.0, agreement, 0, np.array([10.0]))


@SETTINGS
@given(yieldings(), st.lists(st.tuples(unit, cosine), min_size=1, max_size=200))
def test_yielding_stays_between_the_floor_and_the_aggressive_curve(arb, ticks) -> None:
    for c, r in ticks:
        alpha = arb.update(signals(c, r))
        a = arb.aggressive(c)
        assert min(a, arb.floor) - 1e-12 <= alpha <= a + 1e-12


@SETTINGS
@given(yieldings(), st.lists(st.tuples(unit, cosine), max_size=100), unit, unit)
def test_yielding_is_monotone_in_confidence_in_any_state(arb, ticks, c1, c2) -> None:
    for c, r in ticks:
        arb.update(signals(c, r))
    lo, hi = sorted((c1, c2))
    assert arb(lo) <= arb(hi) + 1e-12
    arb._validate()  # the construction-time check, on the state reached


@SETTINGS
@given(yieldings())
def test_yielding_falls_within_window_plus_five_time_constants(arb) -> None:
    c = 1.0  # a(c) = alpha_high
    fight = -1.0  # agree_below >= -0.9 in these draws
    n = math.ceil((arb.window_s + 5 * arb.fall_s) * RATE) + 1
    alphas = [arb.update(signals(c, fight)) for _ in range(n)]
    assert alphas[-1] <= max(arb.floor, arb.alpha_high * math.exp(-5)) + 1e-9
    # nothing changes before the window is full
    early = math.floor(arb.window_s * RATE) - 1
    assert all(a == arb.alpha_high for a in alphas[: max(early, 0)])


@SETTINGS
@given(yieldings())
def test_yielding_recovers_once_the_user_agrees(arb) -> None:
    for _ in range(int((arb.window_s + 5 * arb.fall_s) * RATE) + 2):
        arb.update(signals(1.0, -1.0))
    n = math.ceil(5 * arb.recover_s * RATE)
    alphas = [arb.update(signals(1.0, 1.0)) for _ in range(n)]
    assert alphas[-1] >= arb.alpha_high * (1 - math.exp(-5)) - 1e-9
    assert all(b >= a - 1e-12 for a, b in itertools.pairwise(alphas))


def test_a_short_disagreement_changes_nothing_and_reset_restores_trust() -> None:
    arb = Yielding(threshold=0.4, alpha_high=0.9, window_s=0.3, rate_hz=RATE)
    for _ in range(10):  # 0.2 s of fighting, then agreement
        assert arb.update(signals(0.8, -0.9)) == 0.9
    assert arb.update(signals(0.8, 0.5)) == 0.9
    for _ in range(100):
        arb.update(signals(0.8, -0.9))
    assert arb.update(signals(0.8, -0.9)) == pytest.approx(0.1)  # the floor
    assert arb.update(signals(0.2, -0.9)) == 0.0  # below the threshold: the curve is 0
    arb.reset()
    assert arb(0.8) == 0.9


def _adversarial_at(arb: Yielding, c: float) -> bool:
    """Theorem 1 for one tick from a frozen state: the agreement depends on u, alpha on the
    agreement; sample u in many directions and magnitudes (alpha 1/(k + 1) for every one of
    them would be the adversarial case)."""
    rng = np.random.default_rng(1)
    q = np.zeros(2)
    p = StraightLinePolicy(0.05).step(q, np.array([1.0, 0.0]))
    us, alphas = [], []
    for _ in range(40):
        u = rng.normal(size=2) * rng.uniform(0.001, 0.3)
        cos = float(u.dot(p - q) / (np.linalg.norm(u) * np.linalg.norm(p - q)))
        step = copy.deepcopy(arb)
        alphas.append(step.update(signals(c, cos)))
        us.append(u)
    return is_adversarial(np.array(us), np.tile(p - q, (40, 1)), np.array(alphas))


@SETTINGS
@given(yieldings(), st.lists(st.tuples(unit, cosine), max_size=60), unit)
def test_yielding_is_never_theorem_1s_adversarial_case(arb, ticks, c) -> None:
    for ci, r in ticks:
        arb.update(signals(ci, r))
    assert not _adversarial_at(arb, c)


def test_user_confidence_trusts_a_user_rational_toward_the_predicted_goal() -> None:
    arb = UserConfidence(threshold=0.4, alpha_high=0.9, beta_ref=20.0, floor=0.1)
    rational = TickSignals(0.8, 0.0, 0.0, 0, np.array([200.0, 5.0]))
    elsewhere = TickSignals(0.8, 0.0, 0.0, 0, np.array([5.0, 200.0]))
    aimless = TickSignals(0.8, 0.0, 0.0, 0, np.array([10.0, 4.0]))
    assert arb.update(rational) == pytest.approx(0.9)
    assert arb.update(elsewhere) == pytest.approx(0.1)  # 0.9 * 5/200 < floor
    assert arb.update(aimless) == pytest.approx(0.9 * 10 / 20)
    assert arb.update(TickSignals(0.3, 0.0, 0.0, 0, np.array([200.0, 5.0]))) == 0.0
    arb.reset()
    assert arb(0.8) == 0.9


@SETTINGS
@given(
    st.lists(
        st.tuples(unit, st.lists(st.floats(0.5, 256.0), min_size=2, max_size=2), st.integers(0, 1)),
        min_size=1,
        max_size=50,
    ),
    unit,
    unit,
)
def test_user_confidence_stays_under_the_curve_and_monotone(ticks, c1, c2) -> None:
    arb = UserConfidence(threshold=0.3, alpha_high=0.8, beta_ref=20.0, floor=0.2)
    for c, b, i in ticks:
        alpha = arb.update(TickSignals(c, 0.0, 0.0, i, np.array(b)))
        assert min(arb.aggressive(c), 0.2) - 1e-12 <= alpha <= arb.aggressive(c) + 1e-12
    lo, hi = sorted((c1, c2))
    assert arb(lo) <= arb(hi)


def test_rationality_rises_toward_the_goal_the_user_heads_for_and_falls_for_the_other() -> None:
    goals = np.array([[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]])
    est = RationalityEstimator(memory_m=0.1)
    est.reset(np.zeros(3))
    prior = est.update(np.zeros(3), goals)
    assert prior == pytest.approx([math.sqrt(0.5 * 256)] * 2)
    for k in range(1, 31):  # 30 cm straight at goal 0, 1 cm per tick
        b = est.update(np.array([0.01 * k, 0.0, 0.0]), goals)
    assert b[0] > 100 and b[1] < 5
    still = est.update(np.array([0.3, 0.0, 0.0]), goals)  # no motion: no new evidence
    assert still == pytest.approx(b)
    for k in range(1, 31):  # then 30 cm away from goal 0, toward goal 1
        b = est.update(np.array([0.3 - 0.01 * k, 0.01 * k, 0.0]), goals)
    assert b[1] > 50 and b[0] < 2


def test_online_memory_prediction_adapts_its_rationality() -> None:
    goals = np.array([[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]])
    pred = predictor_from_config(
        {"kind": "memory", "cost": "length", "rationality": "online"}, points=goals
    )
    assert isinstance(pred, MemoryPredictor) and pred.estimator is not None
    pred.reset(np.zeros(3))
    first = pred.rationality
    for k in range(1, 21):
        p = pred.update(np.array([0.01 * k, 0.0, 0.0]))
    assert pred.rationality > 5 * first and p.index == 0 and p.probabilities[0] > 0.99
    with pytest.raises(Exception, match="rationality: 'online'"):
        predictor_from_config(
            {"kind": "memory", "cost": "squared_velocity", "rationality": "online"}, points=goals
        )


def test_the_blender_feeds_and_resets_a_stateful_arbitration() -> None:
    goals = GoalSet(["a", "b"], [[1, 0, 0], [-1, 0, 0]], configurations=[[1, 0, 0], [-1, 0, 0]])
    arb = arbitration_from_config(
        {"kind": "yielding", "threshold": 0.0, "alpha_high": 1.0, "window_s": 0.1},
        rate_hz=RATE,
    )
    blender = PolicyBlender(
        goals=goals,
        predictor=predictor_from_config({"kind": "oracle"}, points=goals, target="a"),
        confidence=ProbabilityConfidence(),
        arbitration=arb,
        policy=StraightLinePolicy(0.02),
        space="configuration",
    )
    blender.reset(np.zeros(3))
    x = np.zeros(3)
    alphas = []
    for _ in range(60):  # the user pulls toward b, 1 cm per tick, against the robot's a
        x = x - np.array([0.01, 0.0, 0.0])
        rec = blender.step(np.zeros(3), x, x=x, robot_x=np.zeros(3))
        alphas.append(rec.alpha)
        assert rec.motion_agreement == pytest.approx(-1.0)
        assert rec.rationality < 11.4  # toward a, the predicted goal: not rational
    assert alphas[0] == 1.0 and alphas[-1] == pytest.approx(0.1)
    blender.reset(np.zeros(3))
    assert arb(1.0) == 1.0

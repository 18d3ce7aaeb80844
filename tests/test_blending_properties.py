"""Property tests (hypothesis): ranges, monotonicity, normalisation, eq. 9 invariances."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from app.blending import (
    Aggressive,
    AmnesicPredictor,
    BlendingError,
    DistanceHinge,
    EntropyConfidence,
    GoalPrediction,
    GoalSet,
    LaplacePredictor,
    Linear,
    MarginConfidence,
    MemoryPredictor,
    PathLengthCost,
    PiecewiseLinear,
    PolicyBlender,
    ProbabilityConfidence,
    SquaredVelocityCost,
    StraightLinePolicy,
    Timid,
)

SETTINGS = settings(max_examples=60, deadline=None)
coord = st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False)
unit = st.floats(0.0, 1.0, allow_nan=False)


@st.composite
def arbitrations(draw):
    kind = draw(st.sampled_from(["timid", "aggressive", "linear", "piecewise"]))
    if kind == "timid":
        return Timid(draw(st.floats(0.01, 0.99)), draw(st.floats(0.01, 1.0)))
    if kind == "aggressive":
        return Aggressive(draw(unit), draw(st.floats(0.01, 1.0)))
    if kind == "linear":
        lo = draw(unit)
        return Linear(lo, draw(st.floats(lo, 1.0)))
    cs = sorted(set(draw(st.lists(unit, min_size=1, max_size=6))))
    alphas = sorted(draw(st.lists(unit, min_size=len(cs), max_size=len(cs))))
    return PiecewiseLinear(list(zip(cs, alphas, strict=True)))


@SETTINGS
@given(arbitrations(), unit, unit)
def test_alpha_in_unit_interval_and_monotone(arb, c1, c2) -> None:
    lo, hi = sorted((c1, c2))
    a_lo, a_hi = arb(lo), arb(hi)
    assert 0.0 <= a_lo <= 1.0 and 0.0 <= a_hi <= 1.0
    assert a_lo <= a_hi + 1e-12


@SETTINGS
@given(st.floats(0.01, 0.99), st.floats(0.01, 1.0), unit)
def test_timid_never_takes_full_charge(alpha_max, saturation, c) -> None:
    assert Timid(alpha_max, saturation)(c) <= alpha_max < 1.0


@st.composite
def scene(draw, max_goals=6, max_dim=4):
    n = draw(st.integers(1, max_goals))
    d = draw(st.integers(1, max_dim))
    goals = draw(arrays(np.float64, (n, d), elements=coord))
    traj = draw(arrays(np.float64, (draw(st.integers(1, 8)), d), elements=coord))
    return goals, traj


def _predictors(goals: np.ndarray):
    return [
        AmnesicPredictor(goals, temperature=0.1),
        MemoryPredictor(goals, cost=PathLengthCost(), rationality=3.0),
        MemoryPredictor(goals, cost=SquaredVelocityCost(steps=3), rationality=3.0),
        LaplacePredictor(goals, cost=SquaredVelocityCost(steps=3), rationality=3.0),
    ]


@SETTINGS
@given(scene())
def test_probabilities_sum_to_one_and_index_is_argmax(sc) -> None:
    goals, traj = sc
    for pred in _predictors(goals):
        pred.reset(traj[0])
        for x in traj:
            out = pred.update(x)
            p = out.probabilities
            assert p.shape == (goals.shape[0],)
            assert np.isfinite(p).all() and (p >= 0).all()
            assert abs(p.sum() - 1.0) < 1e-12
            assert p[out.index] == p.max()


@SETTINGS
@given(scene(), st.integers(0, 2**32 - 1), st.sampled_from(["length", "sqvel"]))
def test_path_cost_cancels_across_goals(sc, seed, cost_name) -> None:
    """C(xi_{S->U}) is shared by every goal: two different trajectories from S to the same U
    give the same posterior, although their costs (generally) differ."""
    goals, traj = sc
    rng = np.random.default_rng(seed)
    s, u = traj[0], traj[-1]
    detour = np.vstack([s, rng.normal(size=(3, goals.shape[1])) * 2.0, u])
    cost = PathLengthCost() if cost_name == "length" else SquaredVelocityCost(steps=2)
    direct = MemoryPredictor(goals, cost=cost, rationality=2.0)
    winding = MemoryPredictor(goals, cost=cost, rationality=2.0)
    direct.reset(s)
    winding.reset(s)
    p_direct = direct.update(u).probabilities
    for x in detour[1:]:
        p_winding = winding.update(x).probabilities
    if cost_name == "length":  # triangle inequality (squared velocity favours more steps)
        assert winding.path_cost >= direct.path_cost - 1e-9
    np.testing.assert_allclose(p_winding, p_direct, atol=1e-9)


@SETTINGS
@given(scene(), st.sampled_from(["length", "sqvel"]))
def test_incremental_equals_batch(sc, cost_name) -> None:
    """The running sum gives eq. 9 evaluated on the whole trajectory from scratch."""
    goals, traj = sc
    cost = PathLengthCost() if cost_name == "length" else SquaredVelocityCost(steps=4)
    pred = MemoryPredictor(goals, cost=cost, rationality=1.5)
    pred.reset(traj[0])
    for x in traj[1:]:
        out = pred.update(x)
    if len(traj) == 1:
        out = pred.update(traj[0])
    c_su = sum(cost.step(a, b) for a, b in itertools.pairwise(traj))
    logits = -1.5 * (c_su + cost.to_go(traj[-1], goals) - cost.to_go(traj[0], goals))
    expected = np.exp(logits - logits.max())
    np.testing.assert_allclose(out.probabilities, expected / expected.sum(), atol=1e-12)


@SETTINGS
@given(arrays(np.float64, st.integers(1, 8), elements=st.floats(0.0, 1.0)), st.floats(0, 5))
def test_confidences_in_unit_interval(raw, distance) -> None:
    if raw.sum() <= 0:
        raw = raw + 1.0
    p = raw / raw.sum()
    pred = GoalPrediction(p, int(p.argmax()))
    for conf in (
        DistanceHinge(0.4),
        ProbabilityConfidence(),
        EntropyConfidence(),
        MarginConfidence(),
    ):
        c = conf(pred, distance)
        assert 0.0 <= c <= 1.0


@SETTINGS
@given(
    arrays(np.float64, 7, elements=coord),
    arrays(np.float64, 7, elements=coord),
    arrays(np.float64, 3, elements=coord),
    arbitrations(),
)
def test_command_is_a_convex_combination(q, u, x, arb) -> None:
    goals = GoalSet(["a", "b"], [[0.5, 0, 0], [0, 0.5, 0]], configurations=[[0.3] * 7, [-0.3] * 7])
    b = PolicyBlender(
        goals=goals,
        predictor=MemoryPredictor(goals.positions, rationality=5),
        confidence=DistanceHinge(1.0),
        arbitration=arb,
        policy=StraightLinePolicy(0.05),
        space="workspace",
    )
    b.reset(np.zeros(3))
    rec = b.step(q, u, x=x)
    assert 0.0 <= rec.alpha <= 1.0
    assert np.isfinite(rec.command).all()
    np.testing.assert_allclose(rec.command, (1 - rec.alpha) * u + rec.alpha * rec.P)
    assert -1.0 <= rec.agreement <= 1.0
    assert np.linalg.norm(rec.P - q) <= 0.05 + 1e-12


big = st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False)


@SETTINGS
@given(
    arrays(np.float64, 7, elements=big),
    arrays(np.float64, 7, elements=big),
    arrays(np.float64, 3, elements=big),
    st.sampled_from(["amnesic", "memory"]),
)
def test_extreme_finite_inputs_never_give_a_nan_command(q, u, x, kind) -> None:
    """Whatever finite input: a finite command or a typed BlendingError, never a NaN."""

    goals = GoalSet(["a", "b"], [[0.5, 0, 0], [0, 0.5, 0]], configurations=[[0.3] * 7, [-0.3] * 7])
    pred = (
        AmnesicPredictor(goals.positions, temperature=0.05)
        if kind == "amnesic"
        else MemoryPredictor(goals.positions, rationality=5)
    )
    b = PolicyBlender(
        goals=goals,
        predictor=pred,
        confidence=DistanceHinge(0.4),
        arbitration=Aggressive(0.4, 0.9),
        policy=StraightLinePolicy(0.05),
        space="workspace",
    )
    b.reset(np.zeros(3))
    try:
        rec = b.step(q, u, x=x)
    except BlendingError:
        return
    assert np.isfinite(rec.command).all() and np.isfinite(rec.probabilities).all()
    assert np.isfinite([rec.alpha, rec.confidence, rec.agreement]).all()

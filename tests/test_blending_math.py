"""Hand-computed values for every formula of the blending formalism, and the paper's cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.blending import (
    Aggressive,
    AmnesicPredictor,
    DistanceHinge,
    EntropyConfidence,
    FunctionArbitration,
    GoalPrediction,
    InvalidArbitrationError,
    InvalidInputError,
    LaplacePredictor,
    Linear,
    MarginConfidence,
    MemoryPredictor,
    NoAssistance,
    OraclePredictor,
    PathLengthCost,
    PiecewiseLinear,
    ProbabilityConfidence,
    SquaredVelocityCost,
    StraightLinePolicy,
    Timid,
    WorkspaceLinePolicy,
    blend,
    is_adversarial,
)

# --- goal prediction ---------------------------------------------------------------------


def test_amnesic_softmin_hand_computed() -> None:
    pred = AmnesicPredictor([[1.0, 0.0], [0.0, 2.0]], temperature=0.5)
    pred.reset([0.0, 0.0])
    out = pred.update([0.0, 0.0])
    # d = (1, 2); logits -d/T = (-2, -4); p0 = 1 / (1 + e^-2)
    assert out.index == 0
    assert out.probabilities[0] == pytest.approx(0.8807970779778823)
    assert out.probabilities.sum() == pytest.approx(1.0)


def test_amnesic_custom_metric() -> None:
    def manhattan(x: np.ndarray, pts: np.ndarray) -> np.ndarray:
        return np.abs(pts - x).sum(axis=1)

    pred = AmnesicPredictor([[1.0, 1.0], [0.0, 1.6]], temperature=1.0, metric=manhattan)
    # Euclidean would pick goal 0 (1.414 < 1.6); Manhattan picks goal 1 (1.6 < 2)
    assert pred.update([0.0, 0.0]).index == 1
    assert pred.update([0.0, 0.0]).probabilities[1] == pytest.approx(1 / (1 + math.exp(-0.4)))


def test_memory_path_length_hand_computed() -> None:
    # S = (0,0) -> (0.5,0) -> U = (0.5,0.5); G1 = (1,0), G2 = (0,2); b = 1
    # C(S->U) = 1; C*(U->G1) = sqrt(.5); C*(U->G2) = sqrt(2.5); C*(S->G1) = 1; C*(S->G2) = 2
    # log w1 = -(1 + .70711 - 1) = -.70711 ; log w2 = -(1 + 1.58114 - 2) = -.58114
    pred = MemoryPredictor([[1.0, 0.0], [0.0, 2.0]], cost=PathLengthCost(), rationality=1.0)
    pred.reset([0.0, 0.0])
    pred.update([0.5, 0.0])
    out = pred.update([0.5, 0.5])
    assert pred.path_cost == pytest.approx(1.0)
    assert out.probabilities[0] == pytest.approx(0.46854958895957566)
    assert out.index == 1


def test_memory_prior_hand_computed() -> None:
    pred = MemoryPredictor([[1.0, 0.0], [0.0, 2.0]], rationality=1.0, prior=[3.0, 1.0])
    pred.reset([0.0, 0.0])
    pred.update([0.5, 0.0])
    out = pred.update([0.5, 0.5])
    # log w + log P(G) with P = (.75, .25)
    assert out.probabilities[0] == pytest.approx(0.725646256475462)
    assert out.index == 0


def test_memory_squared_velocity_hand_computed() -> None:
    # N = 2 steps: C*(x->G) = ||G - x||^2 / 2
    # C(S->U) = .25 + .25 = .5; C*(U->G1) = .25; C*(U->G2) = 1.25; C*(S->G1) = .5; C*(S->G2) = 2
    # log w1 = -(.5 + .25 - .5) = -.25; log w2 = -(.5 + 1.25 - 2) = .25 -> p2 = 1/(1 + e^-.5)
    pred = MemoryPredictor([[1.0, 0.0], [0.0, 2.0]], cost=SquaredVelocityCost(steps=2))
    pred.reset([0.0, 0.0])
    pred.update([0.5, 0.0])
    out = pred.update([0.5, 0.5])
    assert pred.path_cost == pytest.approx(0.5)
    assert out.probabilities[1] == pytest.approx(0.6224593312018546)


def test_memory_rationality_scales_log_odds() -> None:
    pts = [[1.0, 0.0], [0.0, 2.0]]
    log_odds = []
    for b in (1.0, 3.0):
        pred = MemoryPredictor(pts, rationality=b)
        pred.reset([0.0, 0.0])
        p = pred.update([0.5, 0.5]).probabilities
        log_odds.append(math.log(p[1] / p[0]))
    assert log_odds[1] == pytest.approx(3 * log_odds[0])


def test_memory_log_likelihood_does_not_advance() -> None:
    pred = MemoryPredictor([[1.0, 0.0], [0.0, 2.0]])
    pred.reset([0.0, 0.0])
    ll = pred.log_likelihood(np.array([0.5, 0.0]))
    assert pred.path_cost == 0.0
    # -(0.5 + 0.5 - 1), -(0.5 + sqrt(4.25) - 2) - log 2 each
    np.testing.assert_allclose(ll, [-math.log(2), -(0.5 + math.sqrt(4.25) - 2) - math.log(2)])


def test_memory_rejects_bad_use() -> None:
    pred = MemoryPredictor([[1.0, 0.0], [0.0, 2.0]])
    with pytest.raises(InvalidInputError, match="reset"):
        pred.update([0.0, 0.0])
    pred.reset([0.0, 0.0])
    with pytest.raises(InvalidInputError, match=r"x: expected shape \(2,\)"):
        pred.update([0.0, 0.0, 0.0])
    with pytest.raises(InvalidInputError, match="x: contains NaN"):
        pred.update([np.nan, 0.0])
    with pytest.raises(InvalidInputError, match="rationality"):
        MemoryPredictor([[1.0, 0.0]], rationality=-1)
    with pytest.raises(InvalidInputError, match="points: the goal set is empty"):
        MemoryPredictor(np.zeros((0, 2)))
    with pytest.raises(InvalidInputError, match="steps"):
        SquaredVelocityCost(steps=0)


def test_paper_fig3_memory_picks_farther_amnesic_nearer() -> None:
    """Fig. 3: the trajectory so far heads for the farther goal G2 while the current input is
    nearer G1: memory-based prediction (eq. 9, length cost) says G2, amnesic says G1."""
    goals = np.array([[1.0, 1.0], [3.0, 0.0]])  # G1 near, G2 far
    traj = [[0.0, 0.0], [0.5, 0.1], [1.0, 0.3]]
    u = np.array(traj[-1])
    assert np.linalg.norm(u - goals[0]) < np.linalg.norm(u - goals[1])
    mem = MemoryPredictor(goals, rationality=5.0)
    amn = AmnesicPredictor(goals, temperature=0.1)
    mem.reset(traj[0])
    amn.reset(traj[0])
    for x in traj[1:]:
        m, a = mem.update(x), amn.update(x)
    assert m.index == 1
    assert a.index == 0


def test_null_space_effect_with_path_length() -> None:
    """Section 5.2: goals collinear with S tie while U stays on the segment to the nearer one;
    a small sideways deviation tips the prediction to the farther goal."""
    goals = np.array([[1.0, 0.0], [2.0, 0.0]])
    pred = MemoryPredictor(goals, rationality=10.0)
    pred.reset([0.0, 0.0])
    for s in (0.1, 0.3, 0.5, 0.9):
        p = pred.update([s, 0.0]).probabilities
        assert p[0] == pytest.approx(0.5, abs=1e-12)
        assert p[1] == pytest.approx(0.5, abs=1e-12)
    sideways = MemoryPredictor(goals, rationality=10.0)
    sideways.reset([0.0, 0.0])
    out = sideways.update([0.5, 0.05])
    assert out.index == 1
    assert out.probabilities[1] > 0.5


def test_laplace_reduces_to_eq9_with_constant_hessian() -> None:
    pts = np.array([[1.0, 0.0, 0.2], [0.0, 2.0, -0.3], [0.5, 0.5, 0.5]])
    traj = np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.0], [0.3, 0.3, 0.1]])
    mem = MemoryPredictor(pts, cost=SquaredVelocityCost(steps=5), rationality=2.0)
    lap = LaplacePredictor(pts, cost=SquaredVelocityCost(steps=5), rationality=2.0)
    mem.reset(traj[0])
    lap.reset(traj[0])
    for x in traj[1:]:
        np.testing.assert_allclose(lap.update(x).probabilities, mem.update(x).probabilities)


def test_squared_velocity_log_det_hessian_is_exact() -> None:
    """log |H| for N = 4 steps in d = 2: H = 2 T_3 (x) I_2, checked against numpy."""
    cost = SquaredVelocityCost(steps=4)
    t = 2 * np.eye(3) - np.eye(3, k=1) - np.eye(3, k=-1)
    h = np.kron(2 * t, np.eye(2))
    expected = np.linalg.slogdet(h)[1]
    np.testing.assert_allclose(cost.log_det_hessian(np.zeros(2), np.ones((3, 2))), expected)


class _VaryingHessianCost(SquaredVelocityCost):
    """Test cost: squared velocity with a made-up goal-dependent log|H| = ||G - x||."""

    def log_det_hessian(self, x: np.ndarray, points: np.ndarray) -> np.ndarray:
        return np.linalg.norm(points - x, axis=1)


def test_laplace_hessian_factor_hand_computed() -> None:
    # eq. 8 = eq. 9 logits + 0.5 (log|H_SG| - log|H_UG|)
    # S = 0, U = (.5, 0), G1 = (1, 0), G2 = (0, 2); steps = 1, b = 1
    # eq. 9: w1 = -(.25 + .25 - 1) = .5 ; w2 = -(.25 + 4.25 - 4) = -.5
    # Hessian: h1 = .5 (1 - .5) = .25 ; h2 = .5 (2 - sqrt(4.25)) = -0.0307764
    pred = LaplacePredictor([[1.0, 0.0], [0.0, 2.0]], cost=_VaryingHessianCost())
    pred.reset([0.0, 0.0])
    p = pred.update([0.5, 0.0]).probabilities
    l1, l2 = 0.5 + 0.25, -0.5 + 0.5 * (2 - math.sqrt(4.25))
    assert p[0] == pytest.approx(1 / (1 + math.exp(l2 - l1)))


def test_laplace_needs_a_hessian() -> None:
    with pytest.raises(InvalidInputError, match="log_det_hessian"):
        LaplacePredictor([[1.0, 0.0]], cost=PathLengthCost())


def test_oracle_is_one_hot_and_ignores_input() -> None:
    pred = OraclePredictor(3, goal=2)
    pred.reset(None)
    out = pred.update(np.array([100.0, -5.0]))
    assert out.index == 2
    np.testing.assert_array_equal(out.probabilities, [0.0, 0.0, 1.0])
    with pytest.raises(InvalidInputError, match="goal: must be an index in"):
        OraclePredictor(2, goal=2)
    with pytest.raises(InvalidInputError, match="n_goals"):
        OraclePredictor(0, goal=0)


# --- confidence --------------------------------------------------------------------------


def test_confidences_hand_computed() -> None:
    pred = GoalPrediction(np.array([0.7, 0.2, 0.1]), 0)
    assert DistanceHinge(0.4)(pred, 0.1) == pytest.approx(0.75)
    assert DistanceHinge(0.4)(pred, 0.5) == 0.0
    assert DistanceHinge(0.4)(pred, 0.0) == 1.0
    assert ProbabilityConfidence()(pred, 9.0) == pytest.approx(0.7)
    assert MarginConfidence()(pred, 9.0) == pytest.approx(0.5)
    # H = -(.7 ln .7 + .2 ln .2 + .1 ln .1) = .80182 ; 1 - H / ln 3
    assert EntropyConfidence()(pred, 9.0) == pytest.approx(0.27015330083790257)


def test_confidence_extremes() -> None:
    uniform = GoalPrediction(np.full(4, 0.25), 0)
    certain = GoalPrediction(np.array([0.0, 1.0, 0.0]), 1)
    single = GoalPrediction(np.array([1.0]), 0)
    assert EntropyConfidence()(uniform, 0) == pytest.approx(0.0)
    assert EntropyConfidence()(certain, 0) == pytest.approx(1.0)
    assert MarginConfidence()(uniform, 0) == 0.0
    assert MarginConfidence()(certain, 0) == 1.0
    assert EntropyConfidence()(single, 0) == 1.0 and MarginConfidence()(single, 0) == 1.0
    with pytest.raises(InvalidInputError, match="D: must be finite and > 0"):
        DistanceHinge(0.0)


# --- arbitration -------------------------------------------------------------------------


def test_arbitration_hand_computed() -> None:
    timid = Timid(0.5, 0.7)
    assert timid(0.0) == 0.0 and timid(0.35) == pytest.approx(0.25)
    assert timid(0.7) == 0.5 and timid(1.0) == 0.5
    aggressive = Aggressive(0.4, 0.9)
    assert aggressive(0.0) == 0.0 and aggressive(0.3999) == 0.0
    assert aggressive(0.4) == 0.9 and aggressive(1.0) == 0.9
    assert Linear()(0.3) == pytest.approx(0.3)
    assert Linear(0.1, 0.5)(0.5) == pytest.approx(0.3)
    pw = PiecewiseLinear([(0.2, 0.0), (0.6, 0.4), (1.0, 1.0)])
    assert pw(0.0) == 0.0 and pw(0.4) == pytest.approx(0.2)
    assert pw(0.8) == pytest.approx(0.7) and pw(1.0) == 1.0
    assert NoAssistance()(1.0) == 0.0


def test_a_stock_arbitration_is_checked_once_per_parameters(monkeypatch) -> None:
    """Built again with the same parameters (every trial builds its arbitration), a stock kind
    is checked on the grid once; new parameters, a function arbitration and a subclass with an
    alpha of its own are checked each time, and a subclass that decreases is still refused."""
    from app.blending import arbitration as arbitration_module

    checked: list[str] = []
    check = arbitration_module.check_arbitration

    def counted(fn, **kw):
        checked.append(type(fn).__name__)
        check(fn, **kw)

    monkeypatch.setattr(arbitration_module, "_CHECKED", {})
    monkeypatch.setattr(arbitration_module, "check_arbitration", counted)
    for _ in range(3):
        Timid(0.6, 0.4), Aggressive(0.3, 0.9), NoAssistance(), Linear(0.1, 0.8)
    assert checked == ["Timid", "Aggressive", "NoAssistance", "Linear"]
    Timid(0.6, 0.5), PiecewiseLinear([(0.2, 0.0), (1.0, 1.0)])
    PiecewiseLinear([(0.2, 0.0), (1.0, 0.9)])
    FunctionArbitration(lambda c: c), FunctionArbitration(lambda c: c)
    assert checked[4:] == ["Timid", *["PiecewiseLinear"] * 2, *["FunctionArbitration"] * 2]

    class Falling(Timid):
        def __call__(self, c: float) -> float:
            return 1.0 - super().__call__(c)

    with pytest.raises(InvalidArbitrationError, match="must not decrease"):
        Falling(0.6, 0.4)


def test_arbitration_rejects_bad_functions() -> None:
    with pytest.raises(InvalidArbitrationError, match="must not decrease"):
        FunctionArbitration(lambda c: 1.0 - c)
    with pytest.raises(InvalidArbitrationError, match="must stay in"):
        FunctionArbitration(lambda c: 2.0 * c)
    with pytest.raises(InvalidArbitrationError, match="must stay in"):
        FunctionArbitration(lambda c: c - 0.1)
    # a dip between grid points is caught through the declared breakpoint
    with pytest.raises(InvalidArbitrationError, match="must not decrease"):
        FunctionArbitration(lambda c: 0.0 if 0.50005 < c < 0.50007 else c, breakpoints=[0.50006])
    with pytest.raises(InvalidArbitrationError, match="must not decrease"):
        PiecewiseLinear([(0.0, 0.5), (1.0, 0.2)])
    with pytest.raises(InvalidArbitrationError, match="must stay in"):
        PiecewiseLinear([(0.0, 0.5), (1.0, 1.2)])
    with pytest.raises(InvalidInputError, match="strictly increasing"):
        PiecewiseLinear([(0.5, 0.0), (0.5, 0.2)])
    with pytest.raises(InvalidArbitrationError, match="alpha_max: must be >= alpha_min"):
        Linear(0.6, 0.2)
    with pytest.raises(InvalidInputError, match=r"alpha_max: must be in \(0, 1\)"):
        Timid(1.0, 0.5)
    with pytest.raises(InvalidInputError, match=r"threshold: must be in \[0, 1\], got -0.2"):
        Aggressive(-0.2, 0.9)
    assert FunctionArbitration(lambda c: c * c)(0.5) == 0.25


def test_is_adversarial_theorem_1() -> None:
    rng = np.random.default_rng(3)
    u = rng.normal(size=(20, 7))
    k = rng.uniform(0, 5, size=20)
    # p = -k u, alpha = 1/(k+1): every input is cancelled
    assert is_adversarial(u, -k[:, None] * u, 1 / (k + 1))
    # p = 0, alpha = 1
    assert is_adversarial(u, np.zeros_like(u), np.ones(20))
    # a wrong alpha on one sample lets the user escape
    alpha = 1 / (k + 1)
    alpha[4] *= 0.5
    assert not is_adversarial(u, -k[:, None] * u, alpha)
    # a policy that does not oppose the user is not adversarial
    assert not is_adversarial(u, u, np.full(20, 0.5))
    # timid blending toward a fixed goal direction is never adversarial
    p = np.tile(rng.normal(size=7), (20, 1))
    assert not is_adversarial(u, p, np.full(20, 0.5))
    # zero user inputs are excluded; all-zero is an error
    assert is_adversarial(
        np.vstack([u, np.zeros(7)]), np.vstack([-u, np.ones(7)]), np.r_[np.full(20, 0.5), 0.3]
    )
    with pytest.raises(InvalidInputError, match="every sample is zero"):
        is_adversarial(np.zeros((2, 3)), np.zeros((2, 3)), [0.5, 0.5])
    with pytest.raises(InvalidInputError, match="alpha: values must be in"):
        is_adversarial(u, u, np.full(20, 1.5))
    with pytest.raises(InvalidInputError, match="p: expected shape"):
        is_adversarial(u, u[:, :3], np.full(20, 0.5))


# --- policy and blend --------------------------------------------------------------------


def test_straight_line_policy_hand_computed() -> None:
    pol = StraightLinePolicy(1.0)
    np.testing.assert_allclose(pol.step(np.zeros(2), np.array([3.0, 4.0])), [0.6, 0.8])
    np.testing.assert_allclose(pol.step(np.zeros(2), np.array([0.3, 0.4])), [0.3, 0.4])
    np.testing.assert_allclose(pol.step(np.ones(2), np.ones(2)), [1.0, 1.0])


def test_workspace_line_policy_moves_the_end_effector_straight() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(3, 7))

    def fk(q: np.ndarray) -> np.ndarray:
        return a @ q

    def jac(q: np.ndarray) -> np.ndarray:
        return np.vstack([a, np.zeros((3, 7))])

    pol = WorkspaceLinePolicy(fk=fk, jacobian=jac, max_step=0.01, damping=0.0)
    q = rng.normal(size=7)
    goal = fk(q) + np.array([0.3, -0.4, 0.0])
    p = pol.step(q, goal)
    np.testing.assert_allclose(fk(p) - fk(q), [0.006, -0.008, 0.0], atol=1e-12)
    # minimum-norm joint step: orthogonal to the null space of A
    null = np.linalg.svd(a)[2][3:]
    np.testing.assert_allclose(null @ (p - q), 0.0, atol=1e-12)
    with pytest.raises(InvalidInputError, match="fk: returned shape"):
        WorkspaceLinePolicy(fk=lambda q: q, jacobian=jac, max_step=0.01).step(q, goal)


def test_blend_hand_computed() -> None:
    out = blend(np.array([1.0, 0.0]), np.array([0.0, 1.0]), 0.25)
    np.testing.assert_allclose(out, [0.75, 0.25])
    with pytest.raises(InvalidInputError, match="alpha"):
        blend(np.zeros(2), np.zeros(2), 1.5)


def test_zero_prior_excludes_a_goal() -> None:
    pred = MemoryPredictor([[1.0, 0.0], [0.0, 2.0]], prior=[0.0, 1.0])
    pred.reset([0.0, 0.0])
    out = pred.update([0.9, 0.0])  # right next to goal 0, which the prior rules out
    assert out.index == 1
    np.testing.assert_array_equal(out.probabilities, [0.0, 1.0])
    with pytest.raises(InvalidInputError, match="prior: weights must be >= 0 with a positive"):
        MemoryPredictor([[1.0, 0.0], [0.0, 2.0]], prior=[0.0, 0.0])

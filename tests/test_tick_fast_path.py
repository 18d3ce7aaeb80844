"""The control tick's fast paths give what the reference computations give, tick by tick.

Fast paths (issue 24): the IK step (``U``) and the grasp policy (``P``) share one kinematics
pass at ``Q`` (``Kinematics.pose_and_jacobian`` keeps its last pass); both run their numbers
compiled (numba: ``app.teleop.ik_step_core``, ``app.blending.policy_grasp_core``), bit for bit
their Python references (``compiled=False``); the policy's clearance tests toward the same xy
share their overlap spans; the blender works out the agreement of ``P - Q`` and ``U - Q`` only
when it is read. References: each step in Python on its own kinematics (no shared pass), a
policy whose every test works out its own spans, the IK step's formula written out with
``numpy.linalg``, the agreement's cosine with numpy. Amnesic prediction from 3-D points in
scalars equals the metric and softmax it stands for. Compared on every tick of headless trials
(recorded ticks) and on random configurations, goals and rotations. The trial loop's own
shortcuts (issue 24.1, second pass): the objects' derived state kept while no object moved, the
scripted user's noise drawn ahead, the rationality estimate's scalar test for clearly short
steps -- each equal to the computation it stands for. Whole trials are compared across two
trees by ``benchmarks/trial_dump.py``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from app.blending import GraspApproachPolicy, policy_from_config, policy_grasp_core
from app.blending.policy_grasp import rotation_log
from app.blending.prediction.amnesic import AmnesicPredictor, euclidean
from app.blending.prediction.base import softmax
from app.blending.prediction.rationality import GRID, RationalityEstimator
from app.robot.kinematics import Kinematics
from app.teleop import ScriptedInput
from app.teleop.ik_step import IKStep
from app.teleop.scripted import NOISE_BATCH
from app.trial import Trial
from study.protocol import trial_config_from_protocol


def _fresh_pass(kin: Kinematics, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, rotation and Jacobian from a pinocchio pass of its own (nothing kept)."""
    data = kin.model.createData()
    jac = pin.computeFrameJacobian(kin.model, data, q, kin.frame_id, pin.LOCAL_WORLD_ALIGNED)
    placement = data.oMf[kin.frame_id]
    return placement.translation.copy(), placement.rotation.copy(), jac


def _reference_u(ik: IKStep, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``U`` by the IK step's docstring: ``U = clip(Q + dq)``, ``dq = dt J^+ [v; w] +
    dt (I - J^+ J) k_n (q_rest - Q)``, ``J^+ = J^T (J J^T + l^2 I)^-1``, joints capped."""
    x, rot, jac = _fresh_pass(ik.kin, q)
    e = target - x
    v = ik.gain * e
    speed = np.linalg.norm(v)
    if speed > ik.max_speed:
        v *= ik.max_speed / speed
    w = ik.rotation_gain * pin.log3(ik.rotation @ rot.T)
    turn = np.linalg.norm(w)
    if turn > ik.max_angular_speed:
        w *= ik.max_angular_speed / turn
    pinv = jac.T @ np.linalg.inv(jac @ jac.T + ik._damp)
    z = ik.posture_gain * (ik.posture - q)
    dq = ik.dt * (pinv @ np.concatenate([v, w]) + (np.eye(len(q)) - pinv @ jac) @ z)
    biggest = np.abs(dq).max()
    if biggest > ik.max_joint_step:
        dq *= ik.max_joint_step / biggest
    return np.clip(q + dq, ik.kin.lower, ik.kin.upper)


class _UnsharedSpans(GraspApproachPolicy):
    """The grasp policy with every clearance test working out its own overlap spans."""

    def _freedom(self, a: Any, b: Any, frames: Any, *, skip: int = -1, spans: Any = None) -> float:
        return super()._freedom(a, b, frames, skip=skip)

    def _pass_height(
        self, a: Any, b: Any, frames: Any, *, skip: int = -1, spans: Any = None
    ) -> float:
        return super()._pass_height(a, b, frames, skip=skip)


def _reference_agreement(p: np.ndarray, q: np.ndarray, u: np.ndarray) -> float:
    pv, uv = p - q, u - q
    nn = np.linalg.norm(pv) * np.linalg.norm(uv)
    return float(np.clip(pv @ uv / nn, -1.0, 1.0)) if nn > 0.0 else 0.0


def test_a_kept_kinematics_pass_is_the_pass_at_that_configuration(protocol_path: Any) -> None:
    config = trial_config_from_protocol(protocol_path, "easy-right", "aggressive")
    kin = Trial(config, ScriptedInput(seed=0)).kinematics
    rng = np.random.default_rng(7)
    qs = [rng.uniform(kin.lower, kin.upper) for _ in range(40)]
    for i, q in enumerate(qs):
        for again in (q, q.copy(), qs[i - 1], q):  # kept, then another q, then back
            got = kin.pose_and_jacobian(again)
            for a, b in zip(got, _fresh_pass(kin, again), strict=True):
                assert np.array_equal(a, b)


@pytest.mark.parametrize(
    ("task", "mode", "seed"),
    [("easy-right", "aggressive", 0), ("hard-wrong", "timid", 1), ("easy-wrong", "none", 2)],
)
def test_every_tick_u_p_and_agreement_equal_the_reference(
    protocol_path: Any, task: str, mode: str, seed: int
) -> None:
    config = dataclasses.replace(
        trial_config_from_protocol(protocol_path, task, mode), time_limit_s=12.0
    )
    trial = Trial(config, ScriptedInput(seed=seed), seed=seed)
    trial.fused = None  # the components' own calls (the fused step: tests/test_fused_control.py)
    own_ik = IKStep(
        trial.kinematics.copy(),
        rate_hz=config.rate_hz,
        posture=trial.scene.start_q,
        compiled=False,
    )
    policy = trial.blender.policy
    own_policy = policy_from_config(
        dict(config.policy),
        rate_hz=config.rate_hz,
        where="policy",
        arm=trial.scene.arm_model(trial.kinematics.copy()),
    )
    assert type(own_policy) is GraspApproachPolicy
    assert trial.ik.compiled and policy.compiled
    own_policy.__class__ = _UnsharedSpans
    own_policy.compiled = False
    own_policy.set_goals(trial.blender.goals)
    checked = {"u": 0, "p": 0, "agreement": 0}

    tick_ik, tick_policy, tick_blend = trial.ik, policy.step, trial.blender.step
    set_goals = policy.set_goals

    def ik(q: np.ndarray, target: np.ndarray) -> np.ndarray:
        u = tick_ik(q, target)
        assert np.array_equal(u, own_ik(q, target))  # the same step in Python, on its own pass
        np.testing.assert_allclose(u, _reference_u(own_ik, q, target), rtol=0, atol=1e-12)
        checked["u"] += 1
        return u

    def policy_step(q: np.ndarray, target: Any) -> np.ndarray:
        p = tick_policy(q, target)
        assert np.array_equal(p, own_policy.step(q, target))
        assert policy._approaching == own_policy._approaching  # the same hysteresis
        checked["p"] += 1
        return p

    def blend_step(q: np.ndarray, u: np.ndarray, **kw: Any) -> Any:
        rec = tick_blend(q, u, **kw)
        want = _reference_agreement(np.asarray(rec.P), q, u)
        assert rec.agreement == pytest.approx(want, abs=1e-12)
        checked["agreement"] += 1
        return rec

    def goals_moved(goals: Any) -> None:
        set_goals(goals)
        own_policy.set_goals(goals)

    trial.ik = ik  # type: ignore[method-assign]
    policy.step = policy_step  # type: ignore[method-assign]
    policy.set_goals = goals_moved  # type: ignore[method-assign]
    trial.blender.step = blend_step  # type: ignore[method-assign]
    while not trial.done:
        trial.tick()
    assert min(checked.values()) > 100, checked


def test_amnesic_prediction_in_scalars_equals_the_metrics_softmin() -> None:
    """The 3-D Euclidean fast path gives the very numbers of ``euclidean`` and ``softmax``."""
    rng = np.random.default_rng(3)
    for _ in range(3000):
        points = rng.normal(size=(int(rng.integers(1, 6)), 3)) * rng.uniform(0.01, 5.0)
        x = rng.normal(size=3) * rng.uniform(0.01, 5.0)
        predictor = AmnesicPredictor(points, temperature=rng.uniform(0.01, 1.0))
        got = predictor.update(x)
        logits = euclidean(x, predictor.points)
        logits *= -1.0 / predictor.temperature
        want = softmax(logits)
        assert got.index == want.index
        assert got.probabilities.tolist() == want.probabilities.tolist()
    predictor.points = points[::-1].copy()  # set directly: the fast path's copy is stale
    logits = euclidean(x, predictor.points)
    logits *= -1.0 / predictor.temperature
    assert predictor.update(x).probabilities.tolist() == softmax(logits).probabilities.tolist()


def _policies(protocol_path: Any, task: str) -> tuple[Trial, GraspApproachPolicy, Any]:
    """A trial's compiled grasp policy and a reference one (Python, spans unshared)."""
    config = trial_config_from_protocol(protocol_path, task, "aggressive")
    trial = Trial(config, ScriptedInput(seed=0), seed=0)
    ref = policy_from_config(
        dict(config.policy),
        rate_hz=config.rate_hz,
        where="policy",
        arm=trial.scene.arm_model(trial.kinematics.copy()),
    )
    ref.__class__ = _UnsharedSpans
    ref.compiled = False
    ref.set_goals(trial.blender.goals)
    return trial, trial.blender.policy, ref


@pytest.mark.parametrize("task", ["easy-wrong", "hard-right"])
def test_compiled_grasp_policy_equals_the_reference_on_random_configurations(
    protocol_path: Any, task: str
) -> None:
    """Configurations near each grasp (every branch of the carrot: corridor, slot plane,
    aligning, pre-grasp, over the top, straight up) and anywhere within the limits, with the
    hysteresis on or off, and goals moved about: the same ``P`` and the same hysteresis."""
    trial, fast, ref = _policies(protocol_path, task)
    kin = trial.kinematics
    rng = np.random.default_rng(11)
    base = trial.blender.goals
    seen_transit = seen_approach = 0
    for n in range(1500):
        if n % 300 == 299:  # goals moved (and objects with them)
            goals = dataclasses.replace(
                base, positions=base.positions + rng.normal(0.0, 0.03, base.positions.shape)
            )
            fast.set_goals(goals)
            ref.set_goals(goals)
        k = int(rng.integers(len(base)))
        scale = (0.002, 0.02, 0.1, 0.4)[n % 4]
        q = np.clip(base.configurations[k] + rng.normal(0.0, scale, 7), kin.lower, kin.upper)
        if n % 7 == 0:
            q = rng.uniform(kin.lower, kin.upper)
        held = {k} if rng.random() < 0.5 else set()
        fast._approaching, ref._approaching = set(held), set(held)
        p = fast.step(q, k)
        assert np.array_equal(p, ref.step(q, k))
        assert fast._approaching == ref._approaching
        seen_approach += k in fast._approaching
        seen_transit += k not in fast._approaching
    assert seen_approach > 100 and seen_transit > 100


def test_compiled_ik_step_equals_the_reference_on_random_inputs(protocol_path: Any) -> None:
    config = trial_config_from_protocol(protocol_path, "easy-right", "timid")
    kin = Trial(config, ScriptedInput(seed=0)).kinematics
    rng = np.random.default_rng(5)
    for posture in (None, rng.uniform(kin.lower, kin.upper)):
        fast = IKStep(kin, rate_hz=100.0, posture=posture)
        ref = IKStep(kin.copy(), rate_hz=100.0, posture=posture, compiled=False)
        for n in range(800):
            q = rng.uniform(kin.lower, kin.upper)
            target = rng.uniform(-0.8, 0.8, 3) * (0.01 if n % 3 == 0 else 1.0)
            target = target + (kin.pose_and_jacobian(q)[0] if n % 3 == 0 else 0.0)
            kw: dict[str, Any] = {}
            if n % 5 == 0:
                kw["max_speed"] = 0.1
            if n % 4 == 0:
                kw["rotation"] = pin.exp3(rng.normal(0.0, 0.5, 3))
            assert np.array_equal(fast(q, target, **kw), ref(q, target, **kw))


def test_compiled_rotation_log_equals_the_reference() -> None:
    """Random rotations, and ones near 0 and near pi (the branches of the log)."""
    rng = np.random.default_rng(2)
    for n in range(3000):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = (rng.uniform(0.0, np.pi), rng.uniform(0.0, 1e-6), np.pi - rng.uniform(0, 1e-6))[
            n % 3
        ]
        m = pin.exp3(angle * axis)
        assert policy_grasp_core.rotation_log(m) == rotation_log(m.tolist())
    for m in (np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])):
        assert policy_grasp_core.rotation_log(m) == rotation_log(m.tolist())


def test_the_compiled_policy_uses_the_reference_constants() -> None:
    """numba freezes module constants into the machine code: the kernel's copies of the
    policy's thresholds are the policy's."""
    from app.blending import policy_grasp

    assert policy_grasp_core._ROTATION_TOL == policy_grasp.ROTATION_TOL
    assert policy_grasp_core._ALIGN_MARGIN == policy_grasp.ALIGN_MARGIN
    assert policy_grasp_core._HOLD_WIDEN == policy_grasp.HOLD_WIDEN


def test_kept_object_state_is_the_state_worked_out_afresh_every_tick(protocol_path: Any) -> None:
    """The trial keeps the objects' grasp points, cylinders and footprints while no object
    moved (``Trial._objects_moved``) and copies their positions as a slice
    (``Simulation.object_positions``): after every tick they equal what the positions give."""
    config = dataclasses.replace(
        trial_config_from_protocol(protocol_path, "hard-right", "aggressive"), time_limit_s=12.0
    )
    trial = Trial(config, ScriptedInput(seed=3), seed=3)
    sim, goals = trial.sim, trial.scene.goals
    assert sim._objects_xpos is not None  # the scene's objects are consecutive bodies
    kept = moved = 0
    while not trial.done:
        before = trial._grasp_points
        trial.tick()
        pos = sim.data.xpos[sim._object_bodies]
        assert np.array_equal(sim.object_positions(), pos)
        if not sim.objects_live:
            continue
        points = goals.positions + (pos - sim.rest_positions)
        assert np.array_equal(trial._grasp_points, points)
        cylinders = tuple(
            (g[0], g[1], env[0], g[2] + env[1])
            for g, env in zip(points.tolist(), goals.envelopes.tolist(), strict=True)
        )
        assert trial.steering.cylinders == cylinders
        assert trial.steering.footprints == tuple(
            (*c, o.grasp_width / 2)
            for c, o in zip(cylinders, trial.scene.spec.objects, strict=True)
        )
        kept += trial._grasp_points is before
        moved += trial._grasp_points is not before
    assert kept > 100 and moved > 10, (kept, moved)


def test_scripted_noise_drawn_ahead_is_the_noise_drawn_each_tick() -> None:
    """``ScriptedInput._normals``: three numbers a tick, the very numbers of
    ``rng.standard_normal(3)`` tick by tick, across the batches it draws."""
    for seed in (0, 7):
        user, rng = ScriptedInput(seed=seed), np.random.default_rng(seed)
        for _ in range(3 * (NOISE_BATCH // 3) + 5):  # three batches and some
            assert list(user._normals()) == rng.standard_normal(3).tolist()


def _reference_rationality_update(est: Any, x: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``RationalityEstimator.update`` with every step told by the dot product (as before the
    scalar test for clearly short steps)."""
    anchor = est._anchor
    if est._loglik.shape[0] != points.shape[0]:
        est._loglik = np.zeros((points.shape[0], GRID.size))
        est.estimate = est._estimate()
    step = x - anchor
    ss = float(step.dot(step))
    if ss < est._min_step2:
        return est.estimate
    s = math.sqrt(ss)
    to_goal = points - anchor
    cos = to_goal @ step
    cos /= np.maximum(np.sqrt(np.einsum("ij,ij->i", to_goal, to_goal)), 1e-12) * s
    kappa = GRID * s
    est._loglik *= math.exp(-s / est.memory_m)
    est._loglik += np.log(kappa) - kappa - np.log1p(-np.exp(-2.0 * kappa))
    est._loglik += np.multiply.outer(cos, kappa)
    est._anchor = x.copy()
    est._anchor_list = est._anchor.tolist()
    est.direction = step / s
    est.estimate = est._estimate()
    return est.estimate


def test_rationality_tells_short_steps_as_the_dot_product_does() -> None:
    """Steps of every length and steps within a few ulps of ``min_step_m``: the same steps
    count as evidence, the same estimates and directions come out."""
    rng = np.random.default_rng(4)
    points = rng.normal(size=(3, 3))
    fast, ref = RationalityEstimator(), RationalityEstimator()
    start = rng.normal(size=3)
    fast.reset(start)
    ref.reset(start)
    x = start.copy()
    counted = 0
    for n in range(4000):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        if n % 2:  # just around min_step_m from the anchor
            length = fast.min_step_m * (1.0 + rng.integers(-8, 9) * 2.0**-52)
            x = fast._anchor + direction * length
        else:
            x = x + direction * rng.uniform(0.0, 0.004)
        got = fast.update(x, points)
        want = _reference_rationality_update(ref, x, points)
        assert got.tolist() == want.tolist()
        assert fast._anchor.tolist() == ref._anchor.tolist()
        counted += fast.direction is not None and fast._anchor_list == x.tolist()
    assert counted > 500

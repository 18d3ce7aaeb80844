"""The trial's fused control step equals the components' own calls, tick by tick (issue 24.1).

``app.trial.fused_control`` works out ``U``, ``P`` and the command in one compiled call, its
kinematics pass composed from pinocchio's model in compiled code and its damped least squares
in plain loops: the same numbers as pinocchio's pass and the components' compiled steps to a
few ulps (here: within 1e-12), not bit for bit. Checked on every tick of whole trials against
an IK step and a blender of the trial's configuration on their own kinematics (fed the same
``Q``, target and input), on random configurations and on random least-squares problems.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pinocchio as pin
import pytest

from app.blending import DistanceHinge, EntropyConfidence, PiecewiseLinear, Timid
from app.blending.assess_core import dist3, dot3
from app.blending.policy_grasp import GraspApproachPolicy
from app.compiled import cache_dir, dls, dls_loops
from app.robot.kinematics_core import tcp_pose_jacobian
from app.teleop import ScriptedInput
from app.teleop.ik_step import IKStep
from app.trial import Trial
from app.trial.build_blender import build_blender
from app.trial.fused_control import FusedControl, fused_control
from study.protocol import trial_config_from_protocol

ATOL = 1e-12


def test_compiled_kinematics_equal_pinocchio(protocol_path: Any) -> None:
    """Position, rotation and world-aligned Jacobian of the TCP on 2,000 configurations within
    the limits and beyond them."""
    config = trial_config_from_protocol(protocol_path, "easy-right", "timid")
    kin = Trial(config, ScriptedInput(seed=0)).kinematics
    chain = kin.chain()
    assert chain is not None
    rng = np.random.default_rng(3)
    for n in range(2000):
        q = rng.uniform(kin.lower, kin.upper) if n % 2 else rng.uniform(-4.0, 4.0, kin.nq)
        data = kin.model.createData()
        jac = pin.computeFrameJacobian(kin.model, data, q, kin.frame_id, pin.LOCAL_WORLD_ALIGNED)
        placement = data.oMf[kin.frame_id]
        x, rot, j = tcp_pose_jacobian(q, *chain)
        np.testing.assert_allclose(x, placement.translation, rtol=0, atol=ATOL)
        np.testing.assert_allclose(rot, placement.rotation, rtol=0, atol=ATOL)
        np.testing.assert_allclose(j, jac, rtol=0, atol=ATOL)


def test_damped_least_squares_in_loops_equal_the_library_calls() -> None:
    rng = np.random.default_rng(4)
    for n in range(2000):
        jac = rng.normal(0.0, (1e-3, 0.3, 1.0)[n % 3], (6, 7))
        twist = rng.normal(0.0, 0.01, 6)
        z = rng.normal(0.0, 0.01, 7)
        lam2 = 1e-6 * np.eye(6)
        pull = bool(n % 2)
        want, info = dls(jac, twist.copy(), z, pull, lam2)
        got, info_loops = dls_loops(jac, twist.copy(), z, pull, lam2)
        assert info == info_loops == 0
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=ATOL)
    _, info = dls_loops(np.zeros((6, 7)), np.ones(6), np.zeros(7), False, np.zeros((6, 6)))
    assert info == 1  # not positive definite: told, not solved


PROBABILITY_ATOL = 1e-15
"""How far the fused step's ``P(G | xi)`` may be from the components' (the softmax's
exponential is the C library's, not numpy's: 1-2 ulps; measured at most 2.2e-16), and with it a
probability confidence and the ``alpha`` of it."""


@pytest.mark.parametrize(
    ("protocol", "task", "mode", "seed"),
    [
        ("dragan2013", "easy-right", "aggressive", 0),
        ("dragan2013", "hard-wrong", "timid", 1),
        ("dragan2013", "easy-wrong", "none", 2),
        ("dragan2013", "hard-right", "timid", 3),
        ("dragan2013", "hard-wrong", "aggressive", 4),
        ("memory3", "memory", "timid", 0),  # eq. 9, probability confidence
        ("memory3", "memory", "aggressive", 1),  # eq. 9, distance confidence
        ("memory3", "amnesic", "linear", 2),
    ],
)
def test_every_tick_the_fused_step_equals_the_components(
    protocol_path: Any, protocol: str, task: str, mode: str, seed: int
) -> None:
    """Prediction, confidence, arbitration, ``U``, ``P`` and the command in one compiled call
    against an IK step and a blender of the same configuration on their own kinematics (fed
    the same ``Q``, target and input) on every tick: ``G*``, the distance, the rationality and
    the motion agreement bit for bit, a distance confidence and its ``alpha`` too;
    ``P(G | xi)`` (and a probability confidence, its ``alpha``) within ``PROBABILITY_ATOL``;
    ``U``, ``P`` and the command within ``ATOL``."""
    path = protocol_path.parent / f"{protocol}.toml"
    config = dataclasses.replace(trial_config_from_protocol(path, task, mode), time_limit_s=12.0)
    _every_tick_against_the_components(config, seed, compiled=True)


def _every_tick_against_the_components(config: Any, seed: int, *, compiled: bool) -> None:
    """The fused step against the components on every tick of a trial of ``config``;
    ``compiled``: whether the blender's assessment is in the kernel (``step_compiled``) or
    worked out by the blender (``step_joint``)."""
    trial = Trial(config, ScriptedInput(seed=seed), seed=seed)
    fused = trial.fused
    assert isinstance(fused, FusedControl)
    assert (trial.blender.compiled_numbers() is not None) is compiled
    own_kin = trial.kinematics.copy()
    own_ik = IKStep(own_kin, rate_hz=config.rate_hz, posture=trial.scene.start_q)
    own_blender = build_blender(config, trial.scene, own_kin)
    own_blender.reset(trial.scene.start_ee)
    assert type(own_blender.policy) is GraspApproachPolicy
    by_distance = isinstance(own_blender.confidence, DistanceHinge)
    checked = {"ticks": 0, "alpha > 0": 0, "compiled": 0}
    worst = {"u": 0.0, "p": 0.0, "command": 0.0, "probabilities": 0.0, "confidence": 0.0}
    worst["alpha"] = 0.0
    fused_step, set_goals = fused.step, trial.blender.set_goals
    step_compiled = trial.blender.step_compiled

    def counted(*args: Any, **kw: Any) -> Any:
        checked["compiled"] += 1
        return step_compiled(*args, **kw)

    def step(q: np.ndarray, target: np.ndarray, *, x: np.ndarray, robot_x: np.ndarray) -> Any:
        u, rec = fused_step(q, target, x=x, robot_x=robot_x)
        own_u = own_ik(q, target)
        own = own_blender.step(q, own_u, x=x, robot_x=robot_x)
        for name, got, want in (
            ("u", u, own_u),
            ("p", rec.P, own.P),
            ("command", rec.command, own.command),
            ("probabilities", rec.probabilities, own.probabilities),
            ("confidence", rec.confidence, own.confidence),
            ("alpha", rec.alpha, own.alpha),
        ):
            worst[name] = max(worst[name], float(np.abs(np.subtract(got, want)).max()))
        assert (rec.predicted, rec.distance) == (own.predicted, own.distance)
        if by_distance:
            assert (rec.confidence, rec.alpha) == (own.confidence, own.alpha)
        assert (rec.rationality, rec.motion_agreement) == (own.rationality, own.motion_agreement)
        assert rec.agreement == pytest.approx(own.agreement, abs=1e-9)
        assert fused.policy._approaching == own_blender.policy._approaching  # type: ignore[attr-defined]
        checked["ticks"] += 1
        checked["alpha > 0"] += rec.alpha > 0.0
        return u, rec

    def goals_moved(goals: Any, **kw: Any) -> None:
        set_goals(goals, **kw)
        own_blender.set_goals(goals, **kw)

    fused.step = step  # type: ignore[method-assign]
    trial.blender.set_goals = goals_moved  # type: ignore[method-assign]
    trial.blender.step_compiled = counted  # type: ignore[method-assign]
    while not trial.done:
        trial.tick()
    assert checked["ticks"] > 100, checked
    assert checked["compiled"] == (checked["ticks"] if compiled else 0), checked
    if config.arbitration is not None:
        assert checked["alpha > 0"] > 50, checked
    assert max(worst["u"], worst["p"], worst["command"]) <= ATOL, worst
    assert max(worst["probabilities"], worst["confidence"], worst["alpha"]) <= PROBABILITY_ATOL, (
        worst
    )


def test_assessment_s_library_functions_as_the_components_call_them() -> None:
    """``dist3`` is ``math.dist`` and ``dot3`` numpy's ``dot`` of three numbers, bit for bit
    (200,000 random pairs, near and far); a plain ``sqrt`` of the sum of squares is not."""
    rng = np.random.default_rng(5)
    plain = 0
    for n in range(100_000):
        a = rng.normal(0.0, 0.3, 3)
        b = a + rng.normal(0.0, 10.0 ** -(n % 8), 3)
        d = math.dist(a.tolist(), b.tolist())
        assert dist3(a, b) == d, (a, b)
        assert dot3(a, b) == float(a.dot(b)), (a, b)
        plain += math.sqrt(float(np.sum((a - b) ** 2))) != d
    assert plain > 1000  # why math.dist is reproduced, not approximated
    assert dist3(np.zeros(3), np.zeros(3)) == 0.0


def test_other_components_take_the_blender_s_assessment(protocol_path: Any) -> None:
    """A confidence or arbitration of another kind (entropy, piecewise linear) is worked out by
    the blender and the kernel takes ``G*`` and ``alpha`` (``step_joint``): the components'
    numbers on every tick, as above."""
    config = dataclasses.replace(
        trial_config_from_protocol(protocol_path, "easy-wrong", "timid"),
        time_limit_s=6.0,
        confidence=EntropyConfidence(),
        arbitration=PiecewiseLinear([(0.0, 0.0), (0.5, 0.6), (1.0, 0.8)]),
    )
    _every_tick_against_the_components(config, 1, compiled=False)
    blender = Trial(config, ScriptedInput(seed=1)).blender
    assert blender.compiled_numbers() is None
    blender.confidence = DistanceHinge(0.28)
    blender.arbitration = Timid(0.5, 0.7)
    assert blender.compiled_numbers() is not None  # swapped for stock kinds: compiled again


def test_only_the_stock_components_are_fused(protocol_path: Any) -> None:
    """Any other IK step or policy, or one run in Python, takes the components' own calls."""
    config = trial_config_from_protocol(protocol_path, "easy-wrong", "timid")
    trial = Trial(config, ScriptedInput(seed=0))
    assert fused_control(trial.ik, trial.blender) is not None
    trial.ik.compiled = False
    assert fused_control(trial.ik, trial.blender) is None
    trial.ik.compiled = True
    trial.blender.policy.compiled = False  # type: ignore[attr-defined]
    assert fused_control(trial.ik, trial.blender) is None
    straight = dataclasses.replace(
        config, policy={"kind": "straight_line", "max_speed": config.policy["max_speed"]}
    )
    line = Trial(straight, ScriptedInput(seed=0))
    assert line.fused is None
    while line.ticks < 50:
        line.tick()  # the components' calls


def test_a_stateful_arbitration_takes_the_components_calls(protocol_path: Any) -> None:
    """The yielding mode reads the agreement of ``U`` and ``P`` before ``alpha``: the fused
    step hands such a tick to the IK step and ``PolicyBlender.step``, the same numbers."""
    adaptive = protocol_path.parent / "adaptive.toml"
    config = dataclasses.replace(
        trial_config_from_protocol(adaptive, "hard-wrong", "yielding"), time_limit_s=3.0
    )
    trial, twin = (Trial(config, ScriptedInput(seed=1), seed=1) for _ in range(2))
    assert trial.fused is not None
    twin.fused = None
    while not trial.done:
        a, b = trial.tick(), twin.tick()
        assert a is not None and b is not None
        assert np.array_equal(a.command, b.command) and a.alpha == b.alpha


def test_step_joint_checks_what_step_checks(protocol_path: Any) -> None:
    """``x`` before the prediction advances; ``Q``, ``U`` and ``P`` as ``act`` reports them; a
    stateful arbitration refused."""
    from app.blending import BlendingError, InvalidInputError, Yielding

    config = trial_config_from_protocol(protocol_path, "easy-wrong", "timid")
    trial = Trial(config, ScriptedInput(seed=0))
    blender, q = trial.blender, trial.sim.q
    x = trial.user_input.copy()
    fine = (q, q, q, True)
    rec = blender.step_joint(q, x=x, act=lambda k, alpha: fine)
    assert rec.command is q and 0.0 <= rec.confidence <= 1.0
    with pytest.raises(InvalidInputError, match="x: contains NaN"):
        blender.step_joint(q, x=np.array([np.nan, 0.0, 0.0]), act=lambda k, alpha: fine)
    with pytest.raises(InvalidInputError, match="expected shapes"):
        blender.step_joint(q[:3], x=x, act=lambda k, alpha: fine)
    with pytest.raises(BlendingError, match="not 7 finite values"):
        blender.step_joint(q, x=x, act=lambda k, alpha: (q, q, q, False))
    blender.arbitration = Yielding(threshold=0.4, floor=0.2, rate_hz=100.0)
    with pytest.raises(InvalidInputError, match="stateful"):
        blender.step_joint(q, x=x, act=lambda k, alpha: fine)


def test_trial_dump_diff_reports_each_columns_largest_difference(
    protocol_path: Any, tmp_path: Any
) -> None:
    """``benchmarks/trial_dump.py --diff``: zero for equal dumps; a column moved by ``d`` on one
    tick reads ``d``; a changed outcome is told."""
    from benchmarks.trial_dump import diff, record_line

    config = dataclasses.replace(
        trial_config_from_protocol(protocol_path, "easy-right", "timid"), time_limit_s=0.1
    )
    trial = Trial(config, ScriptedInput(seed=0))
    while not trial.done:
        trial.tick()
    records = trial.records
    moved = dataclasses.replace(records[3], command=records[3].command + 2e-15, alpha=0.5)
    head = "trial easy-right timid 0 timeout 10"
    before, after = tmp_path / "before.txt", tmp_path / "after.txt"
    before.write_text("\n".join([head, *map(record_line, records)]) + "\n")
    lines = [record_line(r) for r in records]
    lines[3] = record_line(moved)
    after.write_text("\n".join([head, *lines]) + "\n")
    same = diff(before, before)
    assert all(same["same"].values()) and not any(same["max_abs_difference"].values())
    out = diff(before, after)
    assert out["same"]["outcomes_and_ticks"]
    assert out["max_abs_difference"]["command"] == pytest.approx(2e-15, rel=0.5)
    assert out["max_abs_difference"]["alpha"] == abs(0.5 - records[3].alpha)
    after.write_text("\n".join([head.replace("timeout", "success"), *lines]) + "\n")
    assert not diff(before, after)["same"]["outcomes_and_ticks"]


def test_an_edit_to_any_kernel_source_moves_every_kernels_cache(tmp_path: Path) -> None:
    """numba keys a cache on the kernel's own file; the fused kernel inlines other modules'
    (an edit to ``assess_core.py`` left it running the old code, its tests passing). The
    cache folder is named by every kernel source, so an edit anywhere among them moves it."""
    app = cache_dir().parent.parent
    for rel in ("compiled.py", "blending/assess_core.py", "trial/fused_control_core.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(app / rel, tmp_path / rel)
    (tmp_path / "trial" / "trial.py").write_text("x = 1\n")
    first = cache_dir(tmp_path)
    assert first.parent == tmp_path / "__pycache__" and first == cache_dir(tmp_path)
    (tmp_path / "trial" / "trial.py").write_text("x = 2\n")  # not a kernel's source
    assert cache_dir(tmp_path) == first
    edited = tmp_path / "blending" / "assess_core.py"
    edited.write_text(edited.read_text() + "\n# an edit\n")
    assert cache_dir(tmp_path) != first
    assert str(cache_dir()) == numba.config.CACHE_DIR  # the folder the kernels use

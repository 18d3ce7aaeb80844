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
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from app.blending.policy_grasp import GraspApproachPolicy
from app.compiled import dls, dls_loops
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


@pytest.mark.parametrize(
    ("task", "mode", "seed"),
    [
        ("easy-right", "aggressive", 0),
        ("hard-wrong", "timid", 1),
        ("easy-wrong", "none", 2),
        ("hard-right", "timid", 3),
    ],
)
def test_every_tick_the_fused_step_equals_the_components(
    protocol_path: Any, task: str, mode: str, seed: int
) -> None:
    config = dataclasses.replace(
        trial_config_from_protocol(protocol_path, task, mode), time_limit_s=12.0
    )
    trial = Trial(config, ScriptedInput(seed=seed), seed=seed)
    fused = trial.fused
    assert isinstance(fused, FusedControl)
    own_kin = trial.kinematics.copy()
    own_ik = IKStep(own_kin, rate_hz=config.rate_hz, posture=trial.scene.start_q)
    own_blender = build_blender(config, trial.scene, own_kin)
    own_blender.reset(trial.scene.start_ee)
    assert type(own_blender.policy) is GraspApproachPolicy
    checked = {"ticks": 0, "alpha > 0": 0}
    worst = {"u": 0.0, "p": 0.0, "command": 0.0}
    fused_step, set_goals = fused.step, trial.blender.set_goals

    def step(q: np.ndarray, target: np.ndarray, *, x: np.ndarray, robot_x: np.ndarray) -> Any:
        u, rec = fused_step(q, target, x=x, robot_x=robot_x)
        own_u = own_ik(q, target)
        own = own_blender.step(q, own_u, x=x, robot_x=robot_x)
        for name, got, want in (
            ("u", u, own_u),
            ("p", rec.P, own.P),
            ("command", rec.command, own.command),
        ):
            worst[name] = max(worst[name], float(np.abs(got - want).max()))
        assert (rec.alpha, rec.confidence, rec.distance, rec.predicted) == (
            own.alpha,
            own.confidence,
            own.distance,
            own.predicted,
        )
        assert np.array_equal(rec.probabilities, own.probabilities)
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
    while not trial.done:
        trial.tick()
    assert checked["ticks"] > 100, checked
    if mode != "none":
        assert checked["alpha > 0"] > 50, checked
    assert max(worst.values()) <= ATOL, worst


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

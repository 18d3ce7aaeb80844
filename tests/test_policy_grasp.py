"""The grasping policy's mathematics, kinematically (``Q <- P``, no physics), on the real arm.

The clearance the policy promises is checked against MuJoCo's own geometry (``mj_geomDistance``
between the hand's collision geoms and the objects), not against the policy's box model.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.blending import (
    GoalSet,
    GraspApproachPolicy,
    InvalidInputError,
    OraclePredictor,
    PolicyBlender,
    moved_goals,
    policy_from_config,
)
from app.blending.arbitration import Linear
from app.blending.confidence import DistanceHinge
from app.blending.policy_grasp import ROTATION_TOL, _overlap, rotation_log
from app.robot.arm import LOW_LINKS
from app.robot.kinematics import Kinematics, downward_rotation
from app.robot.scene import PREGRASP_CLEARANCE, Scene, build_scene
from study.protocol.loader import load_protocol

ROOT = Path(__file__).resolve().parents[1]
RATE = 100.0
MAX_SPEED = 1.0
CLEARANCE = 0.02


def _scene(protocol: str, name: str) -> Scene:
    return build_scene(load_protocol(ROOT / "protocols" / f"{protocol}.toml").scenes[name])


class Rig:
    """A scene, its kinematics, the policy and MuJoCo distances from the hand to each object."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.kin: Kinematics = scene.arm.kinematics.copy()
        self.policy = policy_from_config(
            {"kind": "grasp_approach", "max_speed": MAX_SPEED, "clearance": CLEARANCE},
            rate_hz=RATE,
            arm=scene.arm_model(self.kin),
        )
        assert isinstance(self.policy, GraspApproachPolicy)
        self.policy.set_goals(scene.goals)
        m = scene.model
        self.model, self.data = m, mujoco.MjData(m)
        self.hand = [
            g
            for g in range(m.ngeom)
            if m.body(m.geom_bodyid[g]).name in LOW_LINKS and m.geom_contype[g]
        ]
        self.others = [*scene.object_geom_ids, m.geom("table").id]

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Hand to each object, then to the table (m; 0.05 when farther)."""
        d = self.data
        d.qpos[:7] = q
        d.qpos[7:9] = self.scene.spec.gripper_open
        mujoco.mj_kinematics(self.model, d)
        return np.array(
            [
                min(mujoco.mj_geomDistance(self.model, d, g, o, 0.05, None) for g in self.hand)
                for o in self.others
            ]
        )

    def rollout(self, q: np.ndarray, k: int, *, ticks: int = 600, kicks: dict | None = None):
        """``(configurations, TCP positions, rotation errors, min distances)`` until P = Q."""
        qs, xs, rot_errs, dists = [], [], [], []
        goal_rot = self.scene.grasp_rotations[k]
        for t in range(ticks):
            if kicks and t in kicks:
                q = np.clip(q + kicks[t], self.scene.arm.lower, self.scene.arm.upper)
            x, rot = self.kin.fk_rotation(q)
            qs.append(q)
            xs.append(x)
            rot_errs.append(float(np.linalg.norm(rotation_log((goal_rot @ rot.T).tolist()))))
            dists.append(self.distances(q))
            p = self.policy.step(q, k)
            assert np.isfinite(p).all()
            assert np.linalg.norm(p - q) <= self.policy.max_step + 1e-12
            if np.linalg.norm(p - q) < 1e-9:
                break
            q = p
        return np.array(qs), np.array(xs), np.array(rot_errs), np.array(dists)


@pytest.fixture(scope="module")
def rigs() -> dict[str, Rig]:
    return {
        "easy": Rig(_scene("dragan2013", "easy")),
        "hard": Rig(_scene("dragan2013", "hard")),
        "three": Rig(_scene("memory3", "three")),
        "practice": Rig(_scene("memory3", "practice")),
    }


# ---- pieces ----------------------------------------------------------------------------------
def test_rotation_log_is_the_rotation_vector() -> None:
    rng = np.random.default_rng(1)
    rotations = [Rotation.random(random_state=rng) for _ in range(200)]
    rotations += [Rotation.from_rotvec(v) for v in ([0, 0, 0], [1e-9, 0, 0], [0, math.pi, 0])]
    rotations += [Rotation.from_rotvec(u * (math.pi - 1e-7)) for u in np.eye(3)]
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    rotations.append(Rotation.from_rotvec(axis * math.pi))
    for r in rotations:
        w = np.array(rotation_log(r.as_matrix().tolist()))
        assert np.linalg.norm(w) <= math.pi + 1e-9
        back = Rotation.from_rotvec(w).as_matrix()
        assert np.allclose(back, r.as_matrix(), atol=1e-6), (r.as_rotvec(), w)


def test_slab_overlap_is_the_swept_box_with_rounded_corners() -> None:
    """The interval covers every ``s`` at which the moving box comes within ``rho`` of the
    point, and none at which it stays farther than ``rho / cos(22.5 deg)`` (octagonal
    corners)."""
    rng = np.random.default_rng(2)
    s = np.linspace(0.0, 1.0, 2001)
    loose = 1.0 / math.cos(math.pi / 8) + 1e-9
    for _ in range(400):
        p, m = rng.uniform(-0.3, 0.3, 2), rng.uniform(-0.4, 0.4, 2)
        if rng.random() < 0.2:
            m[rng.integers(2)] = 0.0
        angle = rng.uniform(-math.pi, math.pi)
        u = np.array([math.cos(angle), math.sin(angle)])
        v = np.array([-u[1], u[0]])
        hu, hv = rng.uniform(0.01, 0.15, 2)
        rho = rng.uniform(0.0, 0.08)
        rel = p[None, :] - s[:, None] * m[None, :]
        outside = np.maximum(np.abs(np.stack([rel @ u, rel @ v], axis=1)) - [hu, hv], 0.0)
        distance = np.linalg.norm(outside, axis=1)  # from the box to the point, per s
        d = math.sqrt(0.5)
        dirs = (
            (*u, hu),
            (*v, hv),
            (*(d * (u + v)), d * (hu + hv)),
            (*(d * (u - v)), d * (hu + hv)),
        )
        span = _overlap(*p, *m, dirs, rho)
        near = s[distance <= rho]
        if near.size:
            assert (
                span is not None and span[0] <= near.min() + 1e-9 and span[1] >= near.max() - 1e-9
            )
        if span is not None:
            inside = (s >= span[0] + 1e-3) & (s <= span[1] - 1e-3)
            assert (distance[inside] <= rho * loose + 1e-9).all()


def test_goals_are_grasp_frames_with_a_pregrasp_up_the_approach_axis(rigs) -> None:
    scene = rigs["easy"].scene
    goals = scene.goals
    axes = goals.rotations()[:, :, 2]
    assert np.allclose(axes, [0.0, 0.0, -1.0], atol=1e-9)  # top-down: the gripper points down
    pre = goals.pregrasp_positions()
    assert np.allclose(pre, goals.positions - goals.standoffs[:, None] * axes)
    # the open fingertips clear each object's top by PREGRASP_CLEARANCE at the pre-grasp point
    fingertips = pre[:, 2] - scene.arm_model(rigs["easy"].kin).reach_below
    tops = np.array([o.position[2] + o.half_height for o in scene.spec.objects])
    assert np.allclose(fingertips - tops, PREGRASP_CLEARANCE)
    # the envelope: footprint radius, top above the grasp point, half-width across the fingers
    assert np.allclose(goals.envelopes[:, 1], tops - goals.positions[:, 2])
    assert np.allclose(goals.envelopes[goals.index("bottle")], [0.03, 0.03, 0.03])
    moved = moved_goals(goals, {0: (goals.positions[0] + [0.01, 0.0, 0.0], None)})
    assert np.array_equal(moved.standoffs, goals.standoffs)
    assert np.array_equal(moved.envelopes, goals.envelopes)
    assert np.allclose(moved.pregrasp_positions()[0], pre[0] + [0.01, 0.0, 0.0])


def test_grasp_frames_are_checked() -> None:
    with pytest.raises(InvalidInputError, match="standoffs: a pre-grasp standoff"):
        GoalSet(["a"], [[0.5, 0.0, 0.1]], standoffs=[0.05])
    quat = [[0.0, 1.0, 0.0, 0.0]]
    with pytest.raises(InvalidInputError, match="standoffs: expected 1 distances > 0"):
        GoalSet(["a"], [[0.5, 0.0, 0.1]], quat, standoffs=[-0.05])
    with pytest.raises(InvalidInputError, match="envelopes: expected 1 rows"):
        GoalSet(["a"], [[0.5, 0.0, 0.1]], quat, envelopes=[[0.0, 0.03, 0.03]])
    with pytest.raises(InvalidInputError, match="needs grasp frames"):
        GraspApproachPolicy(
            arm=_scene("dragan2013", "easy").arm_model(load_kinematics()),
            max_step=0.01,
            tcp_step=0.003,
            approach_step=0.001,
        ).set_goals(GoalSet(["a"], [[0.5, 0.0, 0.1]]))


def load_kinematics() -> Kinematics:
    return _scene("dragan2013", "easy").arm.kinematics.copy()


def test_the_blender_hands_moved_grasp_frames_to_the_policy(rigs) -> None:
    rig = rigs["easy"]
    scene = rig.scene
    blender = PolicyBlender(
        goals=scene.goals,
        predictor=OraclePredictor(len(scene.goals), goal=0),
        confidence=DistanceHinge(0.4),
        arbitration=Linear(1.0, 1.0),
        policy=rig.policy,
        space="workspace",
    )
    blender.reset(scene.start_ee)
    q = scene.start_q
    rec = blender.step(q, q, x=scene.start_ee)
    assert np.array_equal(rec.P, rig.policy.step(q, 0)) and np.array_equal(rec.command, rec.P)
    shifted = scene.goals.positions[0] + [0.0, 0.02, 0.0]
    blender.set_goals(moved_goals(scene.goals, {0: (shifted, None)}))
    assert np.allclose(rig.policy._goals[0].g, shifted)
    rig.policy.set_goals(scene.goals)


# ---- from the start pose -----------------------------------------------------------------------
@pytest.mark.parametrize(("name", "goal"), [("easy", "box"), ("hard", "box"), ("three", "can"),
                                            ("three", "bottle"), ("practice", "mug")])  # fmt: skip
def test_pregrasp_then_straight_down_the_gripper_axis_to_a_stop(rigs, name: str, goal: str) -> None:
    rig = rigs[name]
    goals = rig.scene.goals
    k = goals.index(goal)
    _, xs, rot_errs, dists = rig.rollout(rig.scene.start_q, k)
    g = goals.positions[k]
    a = goals.rotations()[k][:, 2]
    standoff = goals.standoffs[k]
    # it stops at the grasp pose: P = Q there, the TCP on the grasp point, gripper aligned
    assert np.linalg.norm(xs[-1] - g) < 5e-4 and rot_errs[-1] < 1e-3
    assert len(xs) < 400  # about 3 s at 100 Hz
    rel = xs - g
    above = -(rel @ a)  # height above the grasp point along the axis
    lateral = np.linalg.norm(rel + above[:, None] * a, axis=1)
    # the hand enters the space over the object, below the pre-grasp point, only on the axis
    # and aligned, and it came through the pre-grasp point to get there
    over = (lateral < goals.envelopes[k, 0] + 0.07) & (above < standoff - 1e-3)
    first = int(np.argmax(over))
    assert over[first] and over[first:].all()
    assert (lateral[over] < 2e-3).all() and (rot_errs[over] < ROTATION_TOL).all()
    pregrasp = goals.pregrasp_positions()[k]
    assert np.linalg.norm(xs[:first] - pregrasp, axis=1).min() < 2e-3
    # ... and from there it moves down the axis, at the approach speed (0.1 m/s)
    steps = np.diff(xs[first:], axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    moving = lengths > 1e-5
    along = (steps[moving] @ a) / lengths[moving]
    assert (along > math.cos(math.radians(3.0))).all()
    assert lengths.max() <= 0.1 / RATE * 1.05
    # the hand kept its clearance from every other object and from the table
    others = np.delete(np.arange(len(goals)), k)
    assert dists[:, others].min(initial=1.0) > 0.5 * CLEARANCE
    assert dists[:, -1].min() > 0.005


# ---- from anywhere ---------------------------------------------------------------------------------
def _arbitrary_starts(rig: Rig, n: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Configurations a user may leave the arm in: the TCP anywhere in the reach box up to 0.35
    m, also low between the objects, turned up to 35 deg and tilted up to 17 deg, not touching
    anything."""
    spec = rig.scene.spec
    lo = np.array(spec.reach_lo)
    hi = np.minimum(np.array(spec.reach_hi), [9.0, 9.0, 0.35])
    out: list[np.ndarray] = []
    while len(out) < n:
        tilt = Rotation.from_rotvec([*rng.uniform(-0.3, 0.3, 2), 0.0]).as_matrix()
        rotation = downward_rotation(rng.uniform(-0.6, 0.6)) @ tilt
        r = rig.kin.ik(
            rng.uniform(lo, hi),
            rotation=rotation,
            q0=rig.scene.start_q,
            posture=rig.scene.start_q,
            tol=2e-3,
            rot_tol=2e-2,
        )
        if r.converged and rig.distances(r.q).min() > 0.005:
            out.append(r.q)
    return out


@pytest.mark.parametrize("name", ["easy", "three"])
def test_from_arbitrary_configurations_it_grasps_without_touching_another_object(
    rigs, name: str
) -> None:
    rig = rigs[name]
    rng = np.random.default_rng(3)
    n = len(rig.scene.goals)
    for i, q0 in enumerate(_arbitrary_starts(rig, 8, rng)):
        k = i % n
        _, xs, rot_errs, dists = rig.rollout(q0, k, ticks=900)
        assert np.linalg.norm(xs[-1] - rig.scene.goals.positions[k]) < 5e-4, (i, xs[0])
        assert rot_errs[-1] < 1e-3
        others = np.delete(np.arange(n), k)
        assert dists[:, others].min() > 0.0, (i, xs[0], dists[:, others].min(axis=0))
        assert dists[:, -1].min() > 0.0


def test_feedback_a_pulled_arm_is_taken_up_from_where_it_is(rigs) -> None:
    """The user pulls the arm off its course twice (as a blend with alpha < 1 would); the policy
    continues from where the arm is, around the bottle, to the grasp."""
    rig = rigs["easy"]
    rng = np.random.default_rng(4)
    k = rig.scene.goals.index("box")
    for _ in range(3):
        kicks = {40: rng.uniform(-0.15, 0.15, 7), 150: rng.uniform(-0.15, 0.15, 7)}
        _, xs, _, dists = rig.rollout(rig.scene.start_q, k, ticks=900, kicks=kicks)
        assert np.linalg.norm(xs[-1] - rig.scene.goals.positions[k]) < 5e-4
        assert dists[:, rig.scene.goals.index("bottle")].min() > 0.0


def test_any_configuration_gives_a_finite_limited_step(rigs) -> None:
    rig = rigs["three"]
    rng = np.random.default_rng(5)
    lower, upper = rig.scene.arm.lower, rig.scene.arm.upper
    corners = [lower.copy(), upper.copy(), np.clip(np.zeros(7), lower, upper)]
    for q in corners + [rng.uniform(lower, upper) for _ in range(300)]:
        for k in range(len(rig.scene.goals)):
            p = rig.policy.step(q, k)
            assert np.isfinite(p).all()
            assert np.linalg.norm(p - q) <= rig.policy.max_step + 1e-12
            assert (p >= lower - 1e-12).all() and (p <= upper + 1e-12).all()

"""One arm, two views: MuJoCo and pinocchio agree; IK, scenes and physics behave."""

from __future__ import annotations

import copy
import tomllib

import mujoco
import numpy as np
import pytest

from app.robot import ModelNotFoundError, SceneSpec, UnreachableError, assets
from app.robot.arm import load_arm
from app.robot.errors import PhysicsError
from app.robot.scene import build_scene
from app.robot.simulation import Simulation


@pytest.fixture(scope="module")
def arm():
    return load_arm()


@pytest.fixture(scope="module")
def scenes(protocol_path):
    tables = tomllib.loads(protocol_path.read_text())["scenes"]
    return {name: SceneSpec.from_dict(t, where=f"scenes.{name}") for name, t in tables.items()}


def test_mujoco_and_pinocchio_agree_on_tcp_pose(arm) -> None:
    model = arm.spec().compile()
    data = mujoco.MjData(model)
    site = model.site("tcp").id
    rng = np.random.default_rng(7)
    kin = arm.kinematics
    for _ in range(200):
        q = rng.uniform(arm.lower, arm.upper)
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        pos, rot = kin.fk_rotation(q)
        assert np.abs(data.site_xpos[site] - pos).max() < 1e-9
        assert np.abs(data.site_xmat[site].reshape(3, 3) - rot).max() < 1e-9


def test_jacobian_matches_finite_differences(arm) -> None:
    kin = arm.kinematics
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = rng.uniform(arm.lower + 0.1, arm.upper - 0.1)
        jac = kin.jacobian(q)
        eps = 1e-6
        for j in range(7):
            dq = np.zeros(7)
            dq[j] = eps
            p1, r1 = kin.fk_rotation(q + dq)
            p0, r0 = kin.fk_rotation(q - dq)
            assert np.allclose((p1 - p0) / (2 * eps), jac[:3, j], atol=1e-6)
            w = r1 @ r0.T  # small rotation: skew part / (2 eps) is the angular velocity
            omega = np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]]) / 2
            assert np.allclose(omega / (2 * eps), jac[3:, j], atol=1e-5)


def test_ik_reaches_a_pose_inside_joint_limits(arm) -> None:
    kin = arm.kinematics
    q_goal = np.array([0.3, 0.2, -0.1, -2.0, 0.1, 2.2, 0.9])
    pos, rot = kin.fk_rotation(q_goal)
    res = kin.ik(pos, rotation=rot, q0=np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.785]))
    assert res.converged
    assert np.linalg.norm(kin.fk(res.q) - pos) < 1e-3
    assert arm.within_limits(res.q)


def test_missing_model_says_how_to_install(monkeypatch, tmp_path) -> None:
    monkeypatch.setattr(assets, "_candidates", lambda: [tmp_path / "nowhere"])
    assets.panda_description_dir.cache_clear()
    try:
        with pytest.raises(ModelNotFoundError, match="pip install example-robot-data"):
            assets.panda_description_dir()
    finally:
        assets.panda_description_dir.cache_clear()  # the next caller finds the real files


def test_scene_goals_are_grasp_configurations(scenes, arm) -> None:
    for spec in scenes.values():
        scene = build_scene(spec)
        goals = scene.goals
        assert goals.names == spec.object_names
        for k in range(len(goals)):
            pos, rot = arm.kinematics.fk_rotation(goals.configurations[k])
            assert np.linalg.norm(pos - goals.positions[k]) < 1e-3
            assert rot[2, 2] < -0.999  # gripper pointing down
            obj = spec.objects[k]
            assert np.linalg.norm(goals.positions[k][:2] - obj.position[:2]) < 1e-9
            assert arm.within_limits(goals.configurations[k])


def test_scene_is_compiled_once_and_cached(scenes) -> None:
    spec = scenes["easy"]
    first = build_scene(spec)
    again = build_scene(copy.deepcopy(spec))
    assert again is first  # an equal spec, not just the same object, hits the cache


def test_task_scenes_follow_the_study_design(scenes, arm) -> None:
    for name in ("easy", "hard"):
        scene = build_scene(scenes[name])
        start = scene.start_ee
        dist = np.linalg.norm(scene.goals.positions - start, axis=1)
        assert int(np.argmax(dist)) == scene.target_index, f"{name}: target must be the farther"
        target = scene.goals.positions[scene.target_index]
        other = scene.goals.positions[1 - scene.target_index]
        assert scene.reach.contains(other)
        if name == "easy":
            assert scene.reach.contains(target)
        else:  # just outside the interface's reach, inside the robot's (IK found it)
            assert 0.01 < scene.reach.distance_outside(target) < 0.06
    assert len(build_scene(scenes["training"]).goals) >= 1


def test_unreachable_object_is_named(scenes) -> None:
    d = {
        "target": "jar",
        "start_q": list(scenes["easy"].start_q),
        "reach": {"min": [0.2, -0.5, 0.0], "max": [0.7, 0.5, 0.6]},
        "objects": [
            {"name": "jar", "shape": "cylinder", "size": [0.03, 0.05], "position": [0.5, 0, 0.05]},
            {"name": "can", "shape": "cylinder", "size": [0.03, 0.05], "position": [1.05, 0, 0.05]},
        ],
        "table": {"center": [0.6, 0.0], "half_size": [0.6, 0.6]},
    }
    with pytest.raises(UnreachableError, match="'can'") as info:
        build_scene(SceneSpec.from_dict(d, where="scenes.far"))
    assert info.value.object_name == "can"


def test_servos_track_a_command_and_refuse_nan(scenes) -> None:
    scene = build_scene(scenes["easy"])
    sim = Simulation(scene, physics_dt=0.002)
    goal = scene.goals.configurations[1]
    q = sim.q
    for _ in range(300):  # 3 s at 100 Hz, 1 rad/s per joint at most
        step = np.clip(goal - q, -0.01, 0.01)
        sim.step(q + step, gripper_closed=False, substeps=5)
        q = sim.q
    assert np.abs(sim.q - goal).max() < 2e-3
    assert np.linalg.norm(sim.ee - scene.goals.positions[1]) < 3e-3
    before = sim.data.qpos.copy()
    with pytest.raises(PhysicsError, match="finite"):
        sim.step(np.full(7, np.nan), gripper_closed=False, substeps=5)
    assert np.array_equal(sim.data.qpos, before)
    assert np.all(np.isfinite(sim.data.qpos))

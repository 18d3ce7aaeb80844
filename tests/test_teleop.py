"""Inputs become U: reach clamping, the velocity-limited IK step, gizmo, keyboard, scripted."""

from __future__ import annotations

import threading
import tomllib

import numpy as np
import pytest

from app.robot import SceneSpec
from app.robot.scene import build_scene
from app.teleop import (
    GizmoInput,
    IKStep,
    InputSource,
    InvalidTargetError,
    KeyboardInput,
    ReachRegion,
    ScriptedInput,
    TeleopError,
    TrialObservation,
)


@pytest.fixture(scope="module")
def scene(protocol_path):
    tables = tomllib.loads(protocol_path.read_text())["scenes"]
    return build_scene(SceneSpec.from_dict(tables["easy"], where="scenes.easy"))


def observe(scene, *, q=None, ee=None, user_target=None, t=0.0) -> TrialObservation:
    q = scene.start_q if q is None else q
    ee = scene.arm.kinematics.fk(q) if ee is None else ee
    return TrialObservation(
        t=t,
        q=q,
        ee=ee,
        gripper_closed=False,
        user_target=ee.copy() if user_target is None else user_target,
        reach=scene.reach,
        goal_names=scene.goals.names,
        goal_positions=scene.goals.positions,
        target_index=scene.target_index,
    )


def test_reach_region_clamps_and_rejects_nan() -> None:
    reach = ReachRegion(np.array([0.2, -0.5, 0.0]), np.array([0.6, 0.5, 0.6]))
    assert np.allclose(reach.clamp(np.array([0.9, 0.0, -1.0])), [0.6, 0.0, 0.0])
    assert np.allclose(reach.distance_outside(np.array([0.9, 0.0, 0.3])), 0.3)
    inside = np.array([0.3, 0.1, 0.2])
    assert np.array_equal(reach.clamp(inside), inside)
    for bad in ([np.nan, 0, 0], [np.inf, 0, 0], [0.1, 0.2]):
        with pytest.raises(InvalidTargetError):
            reach.clamp(np.array(bad))
    with pytest.raises(ValueError, match="lo < hi"):
        ReachRegion(np.array([0.5, 0, 0]), np.array([0.4, 1, 1]))


def test_ik_step_moves_toward_target_within_velocity_limits(scene) -> None:
    kin = scene.arm.kinematics.copy()
    step = IKStep(kin, rate_hz=100.0, max_speed=0.3, max_joint_speed=1.0)
    q = scene.start_q.copy()
    target = scene.goals.positions[0] + np.array([0.0, 0.0, 0.05])
    prev = kin.fk(q)
    for _ in range(400):
        u = step(q, target)
        assert np.abs(u - q).max() <= 0.01 + 1e-12  # 1 rad/s at 100 Hz
        x = kin.fk(u)
        assert np.linalg.norm(x - prev) <= 0.3 / 100 * 1.05 + 1e-4  # ~ max_speed per tick
        q, prev = u, x
    pos, rot = kin.fk_rotation(q)
    assert np.linalg.norm(pos - target) < 2e-3
    assert rot[2, 2] < -0.99  # still pointing down


def test_gizmo_is_thread_safe_and_rejects_bad_targets(scene) -> None:
    gizmo = GizmoInput()
    assert isinstance(gizmo, InputSource)
    obs = observe(scene)
    first = gizmo.command(obs)
    assert np.allclose(first.target, obs.ee) and not first.grasp  # starts at the gripper
    stop = threading.Event()
    targets = [np.array([0.3 + 0.001 * i, 0.0, 0.3]) for i in range(200)]

    def ui() -> None:
        for t in targets:
            gizmo.set_target(t)
        stop.set()

    thread = threading.Thread(target=ui)
    thread.start()
    seen = []
    while not stop.is_set():
        seen.append(gizmo.command(obs).target)
    thread.join()
    assert all(
        np.any(np.all(np.isclose(s, targets), axis=1)) or np.allclose(s, obs.ee) for s in seen
    )
    assert np.allclose(gizmo.command(obs).target, targets[-1])
    with pytest.raises(InvalidTargetError):
        gizmo.set_target(np.array([np.nan, 0.0, 0.3]))
    assert np.allclose(gizmo.target, targets[-1])
    gizmo.request_grasp()
    assert gizmo.command(obs).grasp and not gizmo.command(obs).grasp  # one press, one grasp


def test_held_keys_move_at_the_key_speed_and_stay_inside_the_reach(scene) -> None:
    keys = KeyboardInput(speed=0.1, tap_s=0.05)
    start = np.array([0.5, 0.0, 0.3])
    obs = observe(scene, user_target=start)  # 100 Hz: 1 mm per tick and held key
    keys.hold("w")
    keys.hold("w")  # auto-repeat: still one held key
    keys.hold("A")
    cmd = keys.command(obs)
    assert np.allclose(cmd.target, start + np.array([0.001, 0.001, 0.0]))
    keys.release("a")  # held 10 ms of a 50 ms tap: the other 40 ms are owed once
    assert np.allclose(keys.command(obs).target, start + np.array([0.001, 0.004, 0.0]))
    assert np.allclose(keys.command(obs).target, start + np.array([0.001, 0.0, 0.0]))
    keys.release("w")
    assert keys.command(obs).target[0] == pytest.approx(start[0] + 0.002)  # w was held 30 ms
    assert np.allclose(keys.command(obs).target, start) and not keys.moving
    keys.press("s")  # a tap between two ticks still moves speed * tap_s
    assert np.allclose(keys.command(obs).target, start - np.array([0.005, 0.0, 0.0]))
    keys.hold("f")
    low = start
    for _ in range(1000):  # 10 s down, far past the table
        low = keys.command(observe(scene, user_target=low)).target
    assert low[2] == pytest.approx(scene.reach.lo[2])
    keys.release_all(discard=True)
    assert not keys.moving
    keys.press("g")
    assert keys.command(obs).grasp and not keys.command(obs).grasp
    with pytest.raises(TeleopError, match="does nothing"):
        keys.hold("z")


def test_scripted_user_is_seeded_and_speed_limited(scene) -> None:
    def path(seed: int) -> np.ndarray:
        user = ScriptedInput(seed=seed, speed=0.2, noise=0.0)
        obs = observe(scene)
        out = []
        for i in range(50):
            out.append(user.command(observe(scene, user_target=obs.user_target, t=i / 100)).target)
        return np.array(out)

    a, b = path(1), path(1)
    assert np.array_equal(a, b)
    speeds = np.linalg.norm(np.diff(a, axis=0), axis=1) * 100
    assert speeds.max() <= 0.2 + 1e-9
    noisy = [ScriptedInput(seed=s, noise=0.005).command(observe(scene)).target for s in range(3)]
    assert not np.allclose(noisy[0], noisy[1])

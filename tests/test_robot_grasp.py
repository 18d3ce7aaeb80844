"""The robot alone in full charge grasps every object of every shipped scene like a robot should.

For each shipped protocol's scenes (tasks, training and practice; scenes shared by several
protocols run once) and each object as the goal: the protocol's own policy with alpha = 1 (a
constant arbitration), the user idle (``IdleInput``: the target stays at the start) and the
oracle told that object. The runs are the scene as shipped and ``PERTURBED`` seeded variants:
every object moved up to ``PLACE_M`` in x and y and turned up to ``YAW_RAD``, every joint of the
start configuration moved up to ``START_RAD``. In every run the arm must reach the grasp pose
(``POSITION_M``, ``ROTATION_RAD``) within ``REACH_S`` without knocking anything over, touching
any object but its goal, or pushing its goal more than 2 cm; then a grasp request (the page's
grasp control) must lift the goal (outcome ``success``) in at least 95 % of the runs.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from app.blending.policy_grasp import rotation_log
from app.robot.scene_spec import SceneSpec
from app.teleop import IdleInput, TeleopCommand, TrialObservation
from app.trial import Trial, TrialConfig
from app.trial.events import EventKind
from study.protocol.loader import load_protocol

ROOT = Path(__file__).resolve().parents[1]
PERTURBED = 4  # seeded variants per scene and goal, besides the scene as shipped
PLACE_M = 0.01
YAW_RAD = 0.2
START_RAD = 0.05
POSITION_M = 0.003
ROTATION_RAD = math.radians(2.0)
PUSH_M = 0.02
TILT_RAD = 0.1
REACH_S = 4.0
LIFT_SHARE = 0.95


def _shipped() -> Iterator[tuple[str, SceneSpec, dict, object]]:
    """``(protocols, scene, policy table, control)`` per distinct shipped scene."""
    seen: dict[SceneSpec, list[str]] = {}
    out = []
    for path in sorted((ROOT / "protocols").glob("*.toml")):
        if "scenes" not in tomllib.loads(path.read_text()):  # population.toml is no protocol
            continue
        protocol = load_protocol(path)
        for name, spec in protocol.scenes.items():
            key = (spec, tuple(sorted(protocol.policy.items())), protocol.control)
            if key in seen:
                seen[key].append(f"{path.stem}:{name}")
                continue
            seen[key] = [f"{path.stem}:{name}"]
            out.append((seen[key], spec, dict(protocol.policy), protocol.control))
    for names, spec, policy, control in out:
        yield "+".join(names), spec, policy, control


def _perturbed(spec: SceneSpec, rng: np.random.Generator) -> SceneSpec:
    objects = tuple(
        dataclasses.replace(
            o,
            position=(
                o.position[0] + rng.uniform(-PLACE_M, PLACE_M),
                o.position[1] + rng.uniform(-PLACE_M, PLACE_M),
                o.position[2],
            ),
            yaw=o.yaw + rng.uniform(-YAW_RAD, YAW_RAD),
        )
        for o in spec.objects
    )
    start = np.array(spec.start_q) + rng.uniform(-START_RAD, START_RAD, len(spec.start_q))
    return dataclasses.replace(spec, objects=objects, start_q=tuple(start.tolist()))


class GraspOnArrival:
    """The idle user, who asks for the grasp once the gripper has stood still at the grasp
    point for ``still_ticks`` ticks (as a participant would press the grasp key)."""

    def __init__(self, trial_goal: object, *, still_ticks: int = 10) -> None:
        self.idle = IdleInput()
        self.goal = trial_goal  # () -> the goal's grasp point now
        self.still_ticks = still_ticks
        self._prev: np.ndarray | None = None
        self._still = 0
        self.at: float | None = None

    def command(self, obs: TrialObservation) -> TeleopCommand:
        target = self.idle.command(obs).target
        near = np.linalg.norm(obs.ee - self.goal()) < POSITION_M  # type: ignore[operator]
        moving = self._prev is not None and np.linalg.norm(obs.ee - self._prev) > 2e-5
        self._prev = obs.ee.copy()
        self._still = self._still + 1 if near and not moving else 0
        if self.at is None and self._still >= self.still_ticks:
            self.at = obs.t
        return TeleopCommand(target, self.at is not None)


@dataclass(frozen=True)
class Run:
    scene: str
    goal: str
    variant: int
    outcome: str
    reach_s: float | None
    position_m: float
    rotation_rad: float
    pushed_m: float
    max_tilt_rad: float
    knocked: tuple[str, ...]
    touched: tuple[str, ...]

    def __str__(self) -> str:
        return (
            f"{self.scene}/{self.goal}#{self.variant}: {self.outcome}, reached at"
            f" {self.reach_s} s, {self.position_m * 1000:.1f} mm /"
            f" {math.degrees(self.rotation_rad):.2f} deg off, goal pushed"
            f" {self.pushed_m * 100:.1f} cm, knocked {self.knocked}, touched {self.touched}"
        )


def _run(name: str, spec: SceneSpec, goal: str, variant: int, policy: dict, control) -> Run:
    scene = dataclasses.replace(spec, target=goal)
    if variant:
        scene = _perturbed(scene, np.random.default_rng(variant * 7919 + len(goal)))
    config = TrialConfig(
        scene=scene,
        prediction={"kind": "oracle"},
        confidence={"kind": "distance", "D": 0.4},
        arbitration={"kind": "linear", "alpha_min": 1.0, "alpha_max": 1.0},
        policy=policy,
        rate_hz=control.rate_hz,
        physics_dt=control.physics_dt,
        time_limit_s=REACH_S + 3.0,
        lift_height_m=control.lift_height_m,
    )
    trial: Trial
    user = GraspOnArrival(lambda: trial.blender.goals.positions[trial.scene.target_index])
    trial = Trial(config, user)
    k = trial.scene.target_index
    reached: tuple[float, float, float] | None = None
    tilt = 0.0
    while not trial.done:
        trial.tick()
        tilts = trial.sim.object_tilts()
        tilt = max(tilt, float(np.delete(tilts, k).max(initial=0.0)))
        if reached is None and user.at is not None:
            _, rot = trial.kinematics.fk_rotation(trial.sim.q)
            err = np.linalg.norm(rotation_log((trial.scene.grasp_rotations[k] @ rot.T).tolist()))
            moved = trial.sim.object_positions() - trial.sim.rest_positions
            reached = (
                float(np.linalg.norm(trial.sim.ee - trial.blender.goals.positions[k])),
                float(err),
                float(np.linalg.norm(moved[k][:2])),
            )
    if reached is None:
        moved = trial.sim.object_positions() - trial.sim.rest_positions
        reached = (math.inf, math.inf, float(np.linalg.norm(moved[k][:2])))
    events = [e for _, e in trial.events]
    return Run(
        scene=name,
        goal=goal,
        variant=variant,
        outcome=str(trial.outcome),
        reach_s=user.at,
        position_m=reached[0],
        rotation_rad=reached[1],
        pushed_m=reached[2],
        max_tilt_rad=tilt,
        knocked=tuple(e.obj or "" for e in events if e.kind is EventKind.KNOCKED_OVER),
        touched=tuple(e.obj or "" for e in events if e.kind is EventKind.CONTACT and e.obj != goal),
    )


@pytest.fixture(scope="module")
def runs() -> list[Run]:
    out = []
    for name, spec, policy, control in _shipped():
        for goal in spec.object_names:
            for variant in range(PERTURBED + 1):
                out.append(_run(name, spec, goal, variant, policy, control))
    return out


def test_every_shipped_scene_and_goal_is_run(runs: list[Run]) -> None:
    goals = {(r.scene, r.goal) for r in runs}
    scenes = {s for s, _ in goals}
    # dragan2013, adaptive and intent share easy, hard and training; memory3 has three objects
    assert any("dragan2013:easy" in s and "adaptive:easy" in s for s in scenes), scenes
    assert any("memory3:three" in s for s in scenes) and any("practice" in s for s in scenes)
    assert len(goals) >= 9 and len(runs) == len(goals) * (PERTURBED + 1)


def test_the_arm_reaches_each_grasp_pose(runs: list[Run]) -> None:
    late = [str(r) for r in runs if r.reach_s is None or r.reach_s > REACH_S]
    off = [str(r) for r in runs if r.position_m > POSITION_M or r.rotation_rad > ROTATION_RAD]
    assert not late and not off, "\n".join(late + off)


def test_on_the_way_nothing_is_knocked_touched_or_pushed(runs: list[Run]) -> None:
    bad = [
        str(r)
        for r in runs
        if r.knocked or r.touched or r.pushed_m > PUSH_M or r.max_tilt_rad > TILT_RAD
    ]
    assert not bad, "\n".join(bad)


def test_a_grasp_from_there_lifts_the_goal(runs: list[Run]) -> None:
    lifted = [r for r in runs if r.outcome == "success"]
    failed = "\n".join(str(r) for r in runs if r.outcome != "success")
    assert len(lifted) >= LIFT_SHARE * len(runs), failed

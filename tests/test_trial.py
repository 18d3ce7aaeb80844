"""Headless trials: outcomes, the Hard task's need for assistance, bad input, pausing, the CLI."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from app.robot.scene import build_scene
from app.teleop import GizmoInput, IdleInput, ScriptedInput, TeleopCommand, TrialObservation
from app.trial import OUTCOMES, Trial, load_records, run_trial, save_records
from app.trial.events import EventKind, TrialEvent, decode, encode
from study.__main__ import main as study_main
from study.protocol import trial_config_from_protocol
from tests.support.cli import Ran, run_main


@pytest.fixture(scope="module")
def config(protocol_path):
    def make(task: str, mode: str, **changes):
        cfg = trial_config_from_protocol(protocol_path, task, mode)
        return dataclasses.replace(cfg, **changes) if changes else cfg

    return make


def test_easy_task_unassisted_succeeds_with_full_records(config) -> None:
    result = run_trial(config("easy-right", "none", time_limit_s=30), ScriptedInput(seed=0))
    assert result.outcome == "success" and result.success
    assert result.ticks == len(result.records)
    assert result.duration_s == pytest.approx(result.ticks / 100)
    last = result.records[-1]
    assert TrialEvent(EventKind.LIFTED, obj=result.target) in last.events
    assert TrialEvent(EventKind.OUTCOME, text="success") in last.events
    for rec in result.records[::50]:
        assert rec.q.shape == rec.u.shape == rec.p.shape == rec.command.shape == (7,)
        assert rec.user_target.shape == rec.ee.shape == (3,)
        assert rec.probabilities.shape == (2,) and rec.probabilities.sum() == pytest.approx(1)
        assert rec.alpha == 0.0
        json.dumps(rec.as_dict())
    assert any(e == TrialEvent(EventKind.GRASPED, obj=result.target) for _, e in result.events)


@pytest.mark.parametrize("task", ["hard-right", "hard-wrong"])
def test_hard_task_needs_assistance(config, task: str) -> None:
    scene = build_scene(config(task, "none").scene)
    grasp = scene.goals.positions[scene.target_index]  # beyond the reach
    for seed in (0, 1):
        # A user who pushes at the interface's limit and waits: the gripper never gets there.
        patient = ScriptedInput(seed=seed, grasp_when_stalled=False)
        alone = run_trial(config(task, "none", time_limit_s=15), patient)
        assert alone.outcome == "timeout"
        closest = min(np.linalg.norm(r.ee - grasp) for r in alone.records)
        assert closest > 0.02
        clamped = TrialEvent(EventKind.TARGET_CLAMPED)
        assert sum(clamped in r.events for r in alone.records) > 500
        # A user who tries to grasp anyway at the limit: no success either.
        trying = run_trial(config(task, "none", time_limit_s=15), ScriptedInput(seed=seed))
        assert not trying.success and trying.outcome == "timeout"
        for mode in ("timid", "aggressive"):
            helped = run_trial(config(task, mode, time_limit_s=30), ScriptedInput(seed=seed))
            assert max(r.alpha for r in helped.records) > 0.3
            if task == "hard-wrong" and mode == "aggressive":
                # wrong and aggressive, the robot takes the gripper toward the decoy first (for
                # more than a second), keeping its hand clear of it, until the user's input
                # is nearer the target
                decoy = next(n for n in helped.goal_names if n != helped.target)
                k = helped.goal_names.index(decoy)
                wrong = [r for r in helped.records if r.predicted == k and r.alpha >= 0.9]
                assert len(wrong) > 100
                assert not any(
                    e.kind is EventKind.CONTACT and e.obj == decoy for _, e in helped.events
                )
            assert helped.outcome == "success", (task, mode, seed, helped.outcome)


class KnockThenPick:
    """Sweeps the gripper through the bottle high up (knocking it over), holds the hand on the
    bottle's spot for ``block_s``, then leaves; once the bottle stands again a scripted user
    picks it up."""

    def __init__(self, spot: np.ndarray, *, block_s: float = 0.0) -> None:
        self.a = spot + np.array([0.0, 0.18, 0.06])
        self.b = spot + np.array([0.0, -0.22, 0.06])
        self.spot, self.block_s = spot, block_s
        self.knocked_at: float | None = None
        self.picker = ScriptedInput(seed=0)

    def command(self, obs: TrialObservation) -> TeleopCommand:
        if obs.knocks and self.knocked_at is None:
            self.knocked_at = obs.t
        if self.knocked_at is None:
            s = min(max(obs.t - 0.5, 0.0) * 0.3 / 0.4, 1.0)
            return TeleopCommand(self.a + s * (self.b - self.a), False)
        if obs.t - self.knocked_at < self.block_s:  # the hand where the bottle stood
            return TeleopCommand(self.spot + np.array([0.0, 0.0, 0.02]), False)
        return self.picker.command(obs)


def _bottle_target(config, **changes):
    cfg = config("easy-right", "none", time_limit_s=30, **changes)
    return dataclasses.replace(cfg, scene=dataclasses.replace(cfg.scene, target="bottle"))


@pytest.mark.parametrize("block_s", [0.0, 1.5])
def test_a_knocked_target_is_stood_up_again_and_the_run_goes_on(config, block_s) -> None:
    cfg = _bottle_target(config)
    spot = np.array(cfg.scene.object("bottle").position)
    trial = Trial(cfg, KnockThenPick(spot, block_s=block_s))
    k = trial.scene.target_index
    start = trial.sim.object_positions()[k].copy()
    knocked = reset = None
    while not trial.done:
        rec = trial.tick()
        kinds = {e.kind for e in rec.events if e.obj == "bottle"}
        if EventKind.KNOCKED_OVER in kinds:
            knocked = rec.t
        if EventKind.OBJECT_RESET in kinds:
            reset = rec.t
            # upright, still, where it started: at once, not after falling into place
            assert trial.sim.object_tilts()[k] < 1e-6
            np.testing.assert_allclose(trial.sim.object_positions()[k], start, atol=1e-9)
            assert trial.observation().knocks == 1
    assert knocked is not None and reset is not None, "the sweep should knock the bottle over"
    # the run went on: the bottle, stood up again, was lifted after the knock
    assert trial.outcome == "success" and trial.t > reset > knocked
    assert trial.accidents.knocks == {"bottle": 1} and trial.accidents.resets == {"bottle": 1}
    if block_s:  # not while the hand stood in its place
        assert reset - knocked >= block_s
    else:  # as soon as it lay still
        assert reset - knocked < 1.5
    result = trial.result()
    assert result.summary()["knocks"] == 1 and result.count(EventKind.OBJECT_RESET) == 1


def test_the_robot_holds_back_while_its_goal_lies_knocked_over(config) -> None:
    # Aggressive and told the goal (the bottle, near enough for it to take over at once): the
    # robot would drive the gripper to where the bottle must be stood up again. While it lies,
    # alpha is 0; once it stands, the robot takes over.
    # D = 0.4 m: confident at the start (the shipped D keeps it unsure until the user moves)
    confident = {"kind": "distance", "D": 0.4}
    cfg = config("easy-right", "aggressive", time_limit_s=30, confidence=confident)
    cfg = dataclasses.replace(cfg, scene=dataclasses.replace(cfg.scene, target="bottle"))
    trial = Trial(cfg, IdleInput())
    for _ in range(20):
        trial.tick()
    adr = trial.scene.object_qpos_addr[trial.scene.target_index]
    trial.sim.data.qpos[adr + 2] = 0.03  # tipped onto its side where it stood
    trial.sim.data.qpos[adr + 3 : adr + 7] = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]
    alphas, reset = [], None
    while reset is None and trial.t < 5.0:
        rec = trial.tick()
        alphas.append(rec.alpha)
        if any(e.kind is EventKind.OBJECT_RESET for e in rec.events):
            reset = rec.t
    assert reset is not None and trial.accidents.knocks == {"bottle": 1}
    knocked = next(t for t, e in trial.events if e.kind is EventKind.KNOCKED_OVER)
    lying = [a for a, r in zip(alphas, trial.records[20:], strict=True) if knocked < r.t <= reset]
    assert lying and max(lying) == 0.0
    for _ in range(20):
        trial.tick()
    assert trial.records[-1].alpha > 0.5


def test_with_on_knock_end_a_knock_ends_the_run(config) -> None:
    cfg = _bottle_target(config, on_knock="end")
    spot = np.array(cfg.scene.object("bottle").position)
    result = run_trial(cfg, KnockThenPick(spot))
    assert result.outcome == "knocked_over" and not result.success and result.duration_s < 3
    last = result.records[-1].events
    assert TrialEvent(EventKind.KNOCKED_OVER, obj="bottle") in last
    assert TrialEvent(EventKind.OUTCOME, text="knocked_over") in last
    assert not any(e.kind is EventKind.OBJECT_RESET for _, e in result.events)


def test_unassisted_gripper_in_the_hard_task_closes_short_of_the_target(config) -> None:
    # At the reach limit the open fingers end short of the box (along the gripper's slot):
    # whatever the user does there, nothing is grasped and the box is not knocked over.
    result = run_trial(config("hard-right", "none", time_limit_s=30), ScriptedInput(seed=0))
    assert result.outcome == "timeout"
    knocked = TrialEvent(EventKind.KNOCKED_OVER, obj=result.target)
    assert not any(e.kind is EventKind.GRASPED or e == knocked for _, e in result.events)


def test_observation_follows_objects_that_move(config) -> None:
    # The user sees where the objects are now: a lifted bottle's centre and grasp point rise.
    trial = Trial(config("easy-right", "none", time_limit_s=30), ScriptedInput(seed=0))
    start = trial.observation()
    bottle = start.target_index
    np.testing.assert_allclose(start.grasp_points, start.goal_positions)
    rest = np.array(trial.scene.spec.object(trial.scene.target).position)
    np.testing.assert_allclose(start.object_positions[bottle], rest, atol=1e-6)
    rises = []
    while not trial.done:
        trial.tick()
        if trial.outcome is None:
            obs = trial.observation()
            rises.append(obs.object_positions[bottle, 2] - rest[2])
            lift = obs.grasp_points[bottle] - obs.goal_positions[bottle]
            moved = obs.object_positions[bottle] - start.object_positions[bottle]
            np.testing.assert_allclose(lift, moved)
    assert trial.outcome == "success" and max(rises) > 0.03
    np.testing.assert_allclose(
        trial.observation().goal_positions[bottle], start.goal_positions[bottle]
    )


def test_aggressive_gives_more_help_than_timid(config) -> None:
    peak = {}
    for mode in ("timid", "aggressive"):
        result = run_trial(config("hard-right", mode, time_limit_s=30), ScriptedInput(seed=0))
        peak[mode] = max(r.alpha for r in result.records)
    assert peak["aggressive"] > peak["timid"]


def test_grasping_the_other_object_is_an_outcome(config) -> None:
    result = run_trial(config("easy-right", "none", time_limit_s=30), ScriptedInput(goal=1))
    assert result.outcome == "wrong_object" and not result.success
    other = next(name for name in result.goal_names if name != result.target)
    assert TrialEvent(EventKind.LIFTED, obj=other) in result.records[-1].events


def _drop_after_grasp(
    trial: Trial,
    *,
    lands: tuple[tuple[float, float, float], tuple[float, float, float, float]] | None = None,
    watch: Any = None,
) -> list[float]:
    """Run ``trial``; at the first grasp the held mug is pulled down (60 N) until it slips out
    of the fingers. ``lands``: where it comes to rest at the drop, ``(offset from its spot,
    orientation wxyz)``; ``watch(record)``: called after every tick. The times of the
    ``grasped`` events."""
    k = trial.scene.target_index
    body, adr = trial.scene.object_body_ids[k], int(trial.scene.object_qpos_addr[k])
    spot = trial.sim.data.qpos[adr : adr + 3].copy()
    grasps = []
    while not trial.done:
        rec = trial.tick()
        if any(e.kind is EventKind.GRASPED for e in rec.events):
            grasps.append(rec.t)
            if len(grasps) == 1:
                trial.sim.data.xfrc_applied[body, 2] = -60.0
        if any(e.kind is EventKind.DROPPED for e in rec.events):
            trial.sim.data.xfrc_applied[body, 2] = 0.0
            if lands is not None:
                offset, wxyz = lands
                trial.sim.data.qpos[adr : adr + 3] = spot + np.asarray(offset)
                trial.sim.data.qpos[adr + 3 : adr + 7] = wxyz
        if watch is not None:
            watch(rec)
    return grasps


def test_a_held_object_dropped_ends_the_run_under_on_knock_end(config) -> None:
    trial = Trial(config("training", "none", time_limit_s=30, on_knock="end"), ScriptedInput())
    _drop_after_grasp(trial)
    assert trial.outcome == "dropped"
    assert TrialEvent(EventKind.DROPPED, obj=trial.scene.target) in trial.records[-1].events


def test_a_held_object_dropped_is_grasped_again_under_reset(config) -> None:
    trial = Trial(config("training", "none", time_limit_s=30), ScriptedInput())
    grasps = _drop_after_grasp(trial)
    dropped = [t for t, e in trial.events if e == TrialEvent(EventKind.DROPPED, obj="mug")]
    assert len(dropped) == 1 and trial.outcome == "success"
    assert len(grasps) == 2 and grasps[1] > dropped[0]  # the gripper opened, the user tried again


def test_a_dropped_object_is_put_back_where_it_stood(config) -> None:
    """A drop that leaves the mug away from its spot (6 cm aside and turned, as one that
    slipped into another object's way): the arm holds where it lost it, nothing touches it, and
    once it has settled it is put back at its start pose, as an experimenter would, before the
    user's next grasp; it is not a fallen object (the page's fell-over notice), and the run then
    succeeds."""
    trial = Trial(config("training", "none", time_limit_s=30), ScriptedInput())
    k = trial.scene.target_index
    adr = int(trial.scene.object_qpos_addr[k])
    spot = trial.sim.data.qpos[adr : adr + 7].copy()
    dropped, reset, waiting, moved = [], [], [], []
    at_drop = np.zeros(3)

    def watch(rec: Any) -> None:
        nonlocal at_drop
        if dropped and trial.task.phase == "reopening":  # the arm stays where it lost the mug
            moved.append(float(np.linalg.norm(rec.ee - at_drop)))
        if TrialEvent(EventKind.DROPPED, obj="mug") in rec.events:
            dropped.append(rec.t)
            at_drop = rec.ee.copy()
        if TrialEvent(EventKind.OBJECT_RESET, obj="mug") in rec.events:
            reset.append(rec.t)
            np.testing.assert_allclose(trial.sim.data.qpos[adr : adr + 7], spot, atol=1e-9)
        elif dropped and not reset:
            waiting.append((trial.accidents.down, trial.accidents.fallen))

    turned = (np.cos(np.pi / 12), 0.0, 0.0, np.sin(np.pi / 12))  # 30 degrees about the vertical
    grasps = _drop_after_grasp(trial, lands=((0.0, 0.06, 0.0), turned), watch=watch)
    assert len(dropped) == 1 and len(reset) == 1 and len(grasps) == 2
    assert dropped[0] < reset[0] < grasps[1]
    assert waiting and all(down == (k,) and fallen == () for down, fallen in waiting)
    assert moved and max(moved) < 0.005  # it went back to the grasp pose at up to 1 m/s
    assert trial.accidents.knocks["mug"] == 0 and not any(
        e.kind is EventKind.CONTACT for t, e in trial.events if dropped[0] < t < reset[0]
    )  # nothing touched the mug meanwhile
    assert trial.outcome == "success" and trial.accidents.resets["mug"] == 1


def test_a_dropped_object_that_falls_over_is_a_knock(config) -> None:
    """The mug slips out and lands on its side: a knock (counted, and a fallen object: the
    page's fell-over notice), then put back at its start pose like any knocked object."""
    trial = Trial(config("training", "none", time_limit_s=30), ScriptedInput())
    k = trial.scene.target_index
    fallen = []
    on_side = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)
    _drop_after_grasp(
        trial,
        lands=((0.0, 0.06, 0.0), on_side),
        watch=lambda rec: fallen.append(trial.accidents.fallen),
    )
    events = [e for _, e in trial.events]
    assert TrialEvent(EventKind.KNOCKED_OVER, obj="mug") in events
    assert TrialEvent(EventKind.OBJECT_RESET, obj="mug") in events
    assert (k,) in fallen and trial.accidents.knocks["mug"] == 1
    assert trial.outcome == "success"


def test_timeout_and_abort(config) -> None:
    result = run_trial(config("easy-right", "timid", time_limit_s=2), IdleInput())
    assert result.outcome == "timeout" and result.ticks == 200
    trial = Trial(config("easy-right", "timid"), IdleInput())
    trial.tick()
    trial.abort()
    assert trial.outcome == "aborted" and trial.tick() is None
    assert set(OUTCOMES) >= {"success", "wrong_object", "dropped", "knocked_over", "timeout"}


class BadInput:
    """Feeds NaN, far-away, misshapen targets and exceptions, then sensible ones."""

    def __init__(self) -> None:
        self.n = 0

    def command(self, obs: TrialObservation) -> TeleopCommand:
        self.n += 1
        kind = self.n % 5
        if kind == 0:
            return TeleopCommand(np.array([np.nan, 0.0, 0.3]))
        if kind == 1:
            return TeleopCommand(np.array([50.0, -50.0, 9.0]))
        if kind == 2:
            return TeleopCommand(np.array([0.1, 0.2]))
        if kind == 3:
            raise RuntimeError("device unplugged")
        return TeleopCommand(np.array([np.inf, 0.0, 0.0]), grasp=False)


def test_bad_input_is_logged_never_crashes(config) -> None:
    result = run_trial(config("easy-wrong", "aggressive", time_limit_s=1), BadInput())
    assert result.outcome == "timeout"
    events = [encode(e) for r in result.records for e in r.events]
    for expected in ("invalid_target", "target_far_outside", "input_error:RuntimeError"):
        assert expected in events
    for rec in result.records:
        assert np.all(np.isfinite(rec.q)) and np.all(np.isfinite(rec.command))
        assert result.records[0].user_target.shape == (3,)
    reach_hi = np.array([0.75, 0.45, 0.6])
    assert all(np.all(r.user_target <= reach_hi + 1e-12) for r in result.records)


def test_pause_excludes_time_and_is_logged(config) -> None:
    trial = Trial(config("easy-right", "timid", time_limit_s=5), IdleInput())
    for _ in range(10):
        trial.tick()
    trial.pause()
    assert trial.paused and trial.tick() is None and trial.t == pytest.approx(0.1)
    trial.resume()
    rec = trial.tick()
    assert rec.t == pytest.approx(0.11)
    assert rec.events[:2] == (TrialEvent(EventKind.PAUSED), TrialEvent(EventKind.RESUMED))


def test_realtime_run_is_paced_and_pauses_from_another_thread(config) -> None:
    source = GizmoInput()
    trial = Trial(config("easy-right", "timid", time_limit_s=0.5), source)

    def ui() -> None:  # the UI thread: moves the gizmo, pauses for 0.3 s
        time.sleep(0.1)
        source.set_target(np.array([0.5, 0.1, 0.3]))
        trial.pause()
        time.sleep(0.3)
        trial.resume()

    thread = threading.Thread(target=ui)
    start = time.perf_counter()
    thread.start()
    result = trial.run(realtime=True)
    wall = time.perf_counter() - start
    thread.join()
    assert result.outcome == "timeout"
    assert result.duration_s == pytest.approx(0.5)  # paused time is excluded
    assert wall >= 0.5 + 0.3 - 0.05
    assert np.allclose(result.records[-1].user_target, [0.5, 0.1, 0.3])
    assert any(TrialEvent(EventKind.PAUSED) in r.events for r in result.records)


def test_records_round_trip(config, tmp_path) -> None:
    result = run_trial(config("easy-right", "timid", time_limit_s=30), ScriptedInput(seed=2))
    path = save_records(result, tmp_path / "run.npz")
    meta, records = load_records(path)
    assert meta["outcome"] == result.outcome and len(records) == result.ticks
    assert np.array_equal(records[-1].q, result.records[-1].q)
    assert records[-1].events == result.records[-1].events


def test_cli_prints_one_json_line(repo_root, capsys: pytest.CaptureFixture[str]) -> None:
    """The first run is a new ``python -m study trial`` process, as a user runs it; the others
    call the same command line's ``main`` here (no start-up and imports each)."""

    def process(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "study", "trial", *args],
            cwd=repo_root,
            capture_output=True,
            text=True,
            timeout=120,
        )

    def here(*args: str) -> Ran:
        return run_main(study_main, ["trial", *args], capsys)

    def run(*args: str, cli: Callable[..., Any] = here) -> dict:
        proc = cli(*args)
        assert proc.returncode == 0, proc.stderr
        assert "after" in proc.stderr  # the human-readable line; stdout is the JSON alone
        return json.loads(proc.stdout)

    out = run(
        "--task", "hard-right", "--mode", "aggressive", "--input", "scripted", "--seed", "1",
        cli=process,
    )  # fmt: skip
    assert out["success"] is True and out["outcome"] == "success"
    assert out["ticks"] > 0 and out["duration_s"] > 0
    alone = run("--task", "hard-right", "--mode", "none", "--seed", "1", "--time-limit", "8")
    assert alone["success"] is False
    proc = here("--task", "medium")
    assert proc.returncode == 2 and "medium" in proc.stderr
    for bad in (["--seed", "-1"], ["--time-limit", "0"], ["--speed", "fast"]):
        proc = here(*bad)
        assert proc.returncode == 2 and bad[0] in proc.stderr and "Traceback" not in proc.stderr


def test_the_robot_re_aims_at_an_object_that_was_moved(config) -> None:
    """A nudged object's goal follows it (position and grasp configuration), logged per move."""
    trial = Trial(config("easy-wrong", "aggressive", time_limit_s=30), GizmoInput())
    k, other = trial.scene.goals.index("box"), trial.scene.goals.index("bottle")
    start = trial.blender.goals.positions.copy()
    trial.tick()
    trial.sim.set_grip_contacts(True, only=[k])  # a grasp woke the box ...
    addr = trial.scene.object_qpos_addr[k]
    trial.sim.data.qpos[addr : addr + 2] += (0.04, -0.03)  # ... and pushed it 5 cm
    for _ in range(40):
        trial.tick()
    moves = [e for r in trial.records for e in r.events if e.kind is EventKind.GOAL_MOVED]
    assert moves and all(e.obj == "box" for e in moves)
    goals = trial.blender.goals
    assert np.allclose(goals.positions[k], start[k] + (0.04, -0.03, 0.0), atol=3e-3)
    assert np.array_equal(goals.positions[other], start[other])
    # the robot's policy now steers to a grasp configuration over the box where it stands
    assert np.linalg.norm(trial.kinematics.fk(goals.configurations[k]) - goals.positions[k]) < 1e-3
    assert np.array_equal(trial.observation().goal_positions, goals.positions)
    # the logged position is the one the robot used, to the micrometre
    logged = decode(encode(moves[-1]))
    assert logged.obj == "box" and np.allclose(logged.position, goals.positions[k], atol=1e-6)

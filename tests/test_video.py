"""Trial videos: MP4s written headless, and a replay that reproduces the recorded path."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import cv2
import numpy as np
import pandas as pd
import pytest

from app.robot.scene import build_scene
from app.teleop import ScriptedInput
from app.trial import records_from_samples, run_trial, save_records
from app.trial.video import render_live, replay
from study.__main__ import main as study_main
from study.protocol import trial_config_from_protocol
from study.session.sample_writer import sample_row
from study.store import Store
from study.store.schema import SAMPLE_COLUMNS
from tests.support.cli import run_main


def frame_count(path) -> int:
    cap = cv2.VideoCapture(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


@pytest.fixture(scope="module")
def config(protocol_path):
    cfg = trial_config_from_protocol(protocol_path, "easy-right", "timid")
    return dataclasses.replace(cfg, time_limit_s=20)


def test_replay_reproduces_the_recorded_path(config, tmp_path) -> None:
    result = run_trial(config, ScriptedInput(seed=3), seed=3)
    assert result.success
    scene = build_scene(config.scene)
    tcp, bottle = [], []

    def on_frame(rec, data) -> None:
        tcp.append((rec.ee.copy(), data.site_xpos[scene.tcp_site_id].copy()))
        bottle.append(data.xpos[scene.object_body_ids[scene.target_index]].copy())

    out = tmp_path / "replay.mp4"
    frames = replay(scene, result.records, out, fps=10, width=160, height=120, on_frame=on_frame)
    assert frames == len(tcp) == frame_count(out)
    assert frames >= result.duration_s * 10
    recorded, replayed = (np.array(x) for x in zip(*tcp, strict=True))
    assert np.abs(recorded - replayed).max() < 1e-9
    assert recorded[0] == pytest.approx(scene.start_ee, abs=1e-3)
    lifted = bottle[-1][2] - scene.object_rest_z[scene.target_index]
    assert lifted >= config.lift_height_m - 0.005  # the grasped bottle rides with the gripper


def test_live_render_writes_a_readable_mp4(config, tmp_path) -> None:
    out = tmp_path / "live.mp4"
    result, frames = render_live(
        config, ScriptedInput(seed=1), out, seed=1, fps=10, width=160, height=120
    )
    assert result.success
    assert frames == frame_count(out) >= result.duration_s * 10
    cap = cv2.VideoCapture(str(out))
    ok, first = cap.read()
    cap.release()
    assert ok and first.shape == (120, 160, 3) and first.std() > 5  # not a blank frame


def test_render_cli_replays_saved_records(config, repo_root, tmp_path, capsys) -> None:
    result = run_trial(config, ScriptedInput(seed=0))
    records = save_records(result, tmp_path / "run.npz")
    out = tmp_path / "cli.mp4"
    proc = subprocess.run(
        [sys.executable, "-m", "study", "render", "--task", "easy-right", "--replay", str(records),
         "--out", str(out), "--fps", "5", "--width", "96", "--height", "72"],
        cwd=repo_root, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)  # stdout is one JSON line; progress goes to stderr
    assert summary["frames"] == frame_count(out) > 0
    for bad in (["--fps", "0"], ["--width", "-5"], ["--trial-id", "x"]):
        # the same command line's main in this process: no start-up and imports for each
        said = run_main(study_main, ["render", *bad, "--out", str(tmp_path / "bad.mp4")], capsys)
        assert said.returncode == 2 and bad[0] in said.stderr and "Traceback" not in said.stderr
        assert not (tmp_path / "bad.mp4").exists()


def test_replay_from_store_rows(config, tmp_path) -> None:
    """Records rebuilt from the study store's sample rows replay the same path."""
    result = run_trial(config, ScriptedInput(seed=4))
    rows = [sample_row(7, r.tick, r) for r in result.records]
    records = records_from_samples(pd.DataFrame(rows, columns=list(SAMPLE_COLUMNS)))
    assert len(records) == result.ticks
    assert records[-1].events == result.records[-1].events
    scene = build_scene(config.scene)
    seen = []
    replay(scene, records, tmp_path / "store.mp4", fps=5, width=96, height=72,
           on_frame=lambda rec, data: seen.append(
               np.linalg.norm(rec.ee - data.site_xpos[scene.tcp_site_id])))  # fmt: skip
    assert max(seen) < 1e-6


def test_render_cli_replays_a_trial_from_a_study_store(repo_root, tmp_path, capsys) -> None:
    db = tmp_path / "study.sqlite"
    # the store is the render's input, not what is tested: ``run``'s main in this process
    run = run_main(
        study_main, ["run", "--db", str(db), "--participant", "P01", "--seed", "1"], capsys
    )
    assert run.returncode == 0, run.stderr
    store = Store.open_readonly(db)
    trial = next(t for t in store.trials() if t.phase == "task" and t.success)
    out = tmp_path / "store.mp4"
    proc = subprocess.run(
        [sys.executable, "-m", "study", "render", "--store", str(db), "--trial-id",
         str(trial.trial_id), "--out", str(out), "--fps", "5", "--width", "96", "--height", "72"],
        cwd=repo_root, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["outcome"] == "success"
    assert summary["frames"] == frame_count(out) >= trial.duration_s * 5

"""Scene descriptions are validated with errors that name the key and the fix."""

from __future__ import annotations

import copy
import tomllib

import pytest

from app.robot import SceneError, SceneSpec
from app.trial import TrialConfig, TrialConfigError

BASE = {
    "target": "bottle",
    "start_q": [0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.785],
    "reach": {"min": [0.2, -0.5, 0.0], "max": [0.75, 0.5, 0.6]},
    "objects": [
        {
            "name": "bottle",
            "shape": "cylinder",
            "size": [0.03, 0.08],
            "position": [0.55, 0.25, 0.08],
        },
        {
            "name": "box",
            "shape": "box",
            "size": [0.025, 0.025, 0.05],
            "position": [0.45, -0.05, 0.05],
        },
    ],
}


def test_protocol_scenes_parse(protocol_path) -> None:
    scenes = tomllib.loads(protocol_path.read_text())["scenes"]
    assert {"easy", "hard", "training"} <= set(scenes)
    for name, table in scenes.items():
        spec = SceneSpec.from_dict(table, where=f"scenes.{name}")
        assert spec.name == name
        assert spec.target in spec.object_names


def test_overlapping_objects_are_rejected() -> None:
    d = copy.deepcopy(BASE)
    d["objects"][1]["position"] = [0.56, 0.24, 0.05]
    with pytest.raises(SceneError, match="'bottle' and 'box' overlap"):
        SceneSpec.from_dict(d, where="scenes.x")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(target="cup"), r"scenes\.x\.target: 'cup' is not one of"),
        (lambda d: d.update(start_q=[0.0] * 6), r"scenes\.x\.start_q: expected a list of 7"),
        (
            lambda d: d["reach"].update(min=[0.2, -0.5, float("nan")]),
            r"reach\.min\[2\]: expected a finite",
        ),
        (lambda d: d["reach"].update(max=[0.1, 0.5, 0.6]), r"reach: min .* must be below max"),
        (lambda d: d["objects"][0].update(shape="cone"), r"objects\[0\]\.shape: 'cone'"),
        (
            lambda d: d["objects"][0].update(position=[0.55, 0.25, 0.2]),
            r"objects\[0\].*bottom at z",
        ),
        (lambda d: d["objects"][0].update(size=[0.05, 0.08]), r"objects\[0\].*open gripper"),
        (lambda d: d.update(colour="red"), r"scenes\.x: unknown key"),
        (lambda d: d["objects"][1].update(name="bottle"), r"duplicate object name"),
    ],
)
def test_bad_scenes_name_the_key(edit, message: str) -> None:
    d = copy.deepcopy(BASE)
    edit(d)
    with pytest.raises(SceneError, match=message):
        SceneSpec.from_dict(d, where="scenes.x")


def test_trial_config_checks_timing() -> None:
    spec = SceneSpec.from_dict(BASE, where="scenes.x")
    cfg = TrialConfig(
        scene=spec,
        prediction={"kind": "oracle"},
        confidence={"kind": "distance", "D": 0.4},
        arbitration=None,
        policy={"kind": "straight_line", "max_speed": 1.0},
    )
    assert cfg.substeps == 5 and not cfg.assisted
    with pytest.raises(TrialConfigError, match="physics_dt"):
        TrialConfig(
            scene=spec,
            prediction={},
            confidence={},
            arbitration=None,
            policy={},
            rate_hz=100,
            physics_dt=0.003,
        )
    with pytest.raises(TrialConfigError, match="scene"):
        TrialConfig(scene=BASE, prediction={}, confidence={}, arbitration=None, policy={})  # type: ignore[arg-type]

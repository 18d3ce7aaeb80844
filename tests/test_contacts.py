"""Contacts at all times: the arm moves what it runs into, touches are logged, a push off ends."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from app.robot.errors import SceneError
from app.robot.scene_spec import SceneSpec
from app.teleop import ScriptedInput, TeleopCommand, TrialObservation
from app.trial import OUTCOMES, Trial, run_trial
from app.trial.contacts import ContactLog
from app.trial.events import EventKind, TrialEvent, encode
from study.export.tables import _with_event_totals
from study.protocol import trial_config_from_protocol


class Sweep:
    """Hold the start for a moment, then slide the target from ``a`` to ``b`` at ``speed`` m/s."""

    def __init__(self, a: tuple[float, ...], b: tuple[float, ...], *, speed: float) -> None:
        self.a, self.b, self.speed = np.array(a), np.array(b), speed

    def command(self, obs: TrialObservation) -> TeleopCommand:
        span = float(np.linalg.norm(self.b - self.a))
        s = min(max(obs.t - 0.5, 0.0) * self.speed / span, 1.0)
        return TeleopCommand(self.a + s * (self.b - self.a), False)


def _scene(protocol_path, **changes) -> SceneSpec:
    cfg = trial_config_from_protocol(protocol_path, "easy-right", "none")
    return dataclasses.replace(cfg.scene, **changes)


def _config(protocol_path, scene: SceneSpec, *, time_limit_s: float = 8.0):
    cfg = trial_config_from_protocol(protocol_path, "easy-right", "none")
    return dataclasses.replace(cfg, scene=scene, time_limit_s=time_limit_s)


def _through_box(protocol_path, contacts: str):
    scene = _scene(protocol_path, contacts=contacts)
    box = np.array(scene.object("box").position)
    # the gripper comes down beside the box and sweeps through it, away from the bottle
    a, b = box + np.array([0.0, 0.15, 0.03]), box + np.array([0.0, -0.08, 0.03])
    trial = Trial(_config(protocol_path, scene, time_limit_s=6.0), Sweep(a, b, speed=0.1))
    start = trial.sim.object_positions()[scene.object_names.index("box")].copy()
    result = trial.run()
    moved = trial.sim.object_positions()[scene.object_names.index("box")] - start
    return result, float(np.linalg.norm(moved[:2])), trial


def test_the_gripper_no_longer_passes_through_an_object(protocol_path) -> None:
    result, moved, trial = _through_box(protocol_path, "always")
    events = [e for _, e in result.events]
    assert moved > 0.03, "the box should be pushed aside"
    touches = [e for e in events if e.kind is EventKind.CONTACT]
    assert touches and all(e.obj == "box" for e in touches)
    ends = [e for e in events if e.kind is EventKind.CONTACT_END]
    assert len(ends) == len(touches)  # every touch ends (at the latest with the trial)
    impulse = sum(e.impulse_ns for e in ends)
    assert impulse > 0.0 and trial.contacts.impulse_ns == pytest.approx(impulse, rel=1e-3)
    assert trial.contacts.count == len(touches)


def test_grasp_only_contacts_restore_the_earlier_behaviour(protocol_path) -> None:
    result, moved, _ = _through_box(protocol_path, "grasp")
    assert moved < 1e-3
    contact = (EventKind.CONTACT, EventKind.CONTACT_END)
    assert not any(e.kind in contact for _, e in result.events)


def _edge_scene(protocol_path) -> SceneSpec:
    """A small table: a 5 cm cube stands 5 cm from its edge."""
    return SceneSpec.from_dict(
        {
            "target": "bottle",
            "start_q": list(_scene(protocol_path).start_q),
            "reach": {"min": [0.2, -0.45, 0.02], "max": [0.75, 0.45, 0.6]},
            "table": {"center": [0.5, 0.0], "half_size": [0.25, 0.2]},
            "objects": [
                {
                    "name": "bottle",
                    "shape": "cylinder",
                    "size": [0.03, 0.08],
                    "position": [0.55, -0.1, 0.08],
                },
                {
                    "name": "box",
                    "shape": "box",
                    "size": [0.025, 0.025, 0.025],
                    "position": [0.45, 0.12, 0.025],
                },
            ],
        },
        where="scenes.edge",
    )


EDGE_SWEEP = ((0.45, 0.0, 0.03), (0.45, 0.42, 0.03))  # the gripper sweeps the box off, low
# enough that it slides rather than tips


def test_an_object_pushed_off_the_table_ends_the_trial_under_on_knock_end(protocol_path) -> None:
    cfg = dataclasses.replace(_config(protocol_path, _edge_scene(protocol_path)), on_knock="end")
    result = run_trial(cfg, Sweep(*EDGE_SWEEP, speed=0.25))
    events = [e for _, e in result.events]
    assert result.outcome == "pushed_off" and "pushed_off" in OUTCOMES
    assert TrialEvent(EventKind.PUSHED_OFF, obj="box") in events
    assert any(e.kind is EventKind.CONTACT and e.obj == "box" for e in events)


def test_an_object_pushed_off_the_table_is_put_back_and_the_run_goes_on(protocol_path) -> None:
    scene = _edge_scene(protocol_path)
    trial = Trial(_config(protocol_path, scene), Sweep(*EDGE_SWEEP, speed=0.25))
    box = scene.object_names.index("box")
    start = trial.sim.object_positions()[box].copy()
    result = trial.run()
    events = [(t, e) for t, e in result.events if e.obj == "box"]
    off = [t for t, e in events if e.kind is EventKind.PUSHED_OFF]
    back = [t for t, e in events if e.kind is EventKind.OBJECT_RESET]
    assert len(off) == 1 and len(back) == 1 and back[0] > off[0]
    assert result.outcome == "timeout" and result.duration_s > back[0] + 1.0
    # on the table where it stood, upright, and still there at the end
    np.testing.assert_allclose(trial.sim.object_positions()[box], start, atol=2e-3)
    assert trial.sim.object_tilts()[box] < 0.05
    assert trial.accidents.pushes == {"box": 1} and result.summary()["pushed_off"] == 1


def test_a_grasp_is_not_a_collision() -> None:
    log = ContactLog(["bottle", "box"])
    finger, hand = 2, 1
    assert log.update([(finger, 0, 5.0)], dt=0.01, grasping=True, held=None) == []
    assert log.update([(finger, 0, 5.0), (hand, 1, 2.0)], dt=0.01, grasping=True) == [
        TrialEvent(EventKind.CONTACT, part="hand", obj="box")
    ]
    assert log.update([], dt=0.05, grasping=False) == []  # a short break continues the touch
    assert log.update([(hand, 1, 2.0)], dt=0.01, grasping=False) == []
    (end,) = log.update([], dt=0.1, grasping=False)
    assert encode(end) == "contact_end:hand:box:0.0400"
    assert log.count == 1 and log.impulse_ns == pytest.approx(0.04)


def test_contacts_are_a_measure_per_trial_in_the_export() -> None:
    samples = pd.DataFrame(
        {
            "trial_id": [1, 1, 1, 2],
            "events": [
                json.dumps(["contact:hand:box"]),
                json.dumps(["contact_end:hand:box:0.2500", "contact:leftfinger:bottle"]),
                json.dumps(["contact_end:leftfinger:bottle:0.0500", "knocked_over:bottle"]),
                json.dumps(["knocked_over:box", "object_reset:box", "outcome:success"]),
            ],
        }
    )
    trials = pd.DataFrame({"trial_id": [1, 2, 3], "target": ["box", "box", "box"]})
    trials = _with_event_totals(trials, samples)
    assert list(trials["contacts"]) == [2, 0, 0]
    assert list(trials["contact_impulse_ns"]) == pytest.approx([0.3, 0.0, 0.0])
    assert list(trials["knocks"]) == [1, 1, 0] and list(trials["target_knocks"]) == [0, 1, 0]
    assert list(trials["object_resets"]) == [0, 1, 0]


def test_the_protocol_chooses_the_contact_mode(protocol_path) -> None:
    base = {
        "target": "box",
        "start_q": list(_scene(protocol_path).start_q),
        "reach": {"min": [0.2, -0.45, 0.02], "max": [0.75, 0.45, 0.6]},
        "objects": [
            {
                "name": "box",
                "shape": "box",
                "size": [0.025, 0.025, 0.035],
                "position": [0.6, 0.0, 0.035],
            },
        ],
    }
    assert SceneSpec.from_dict(base).contacts == "always"
    assert SceneSpec.from_dict({**base, "contacts": "grasp"}).contacts == "grasp"
    with pytest.raises(SceneError, match=r"scene\.contacts: 'sometimes'; use 'always'"):
        SceneSpec.from_dict({**base, "contacts": "sometimes"})


def test_arm_contacts_reports_every_arm_object_point_with_its_force(protocol_path) -> None:
    """``Simulation.arm_contacts`` against MuJoCo's contact list read point by point, by body
    name, on every tick of a sweep through the box (the arm pushing it) and a grasp: the same
    points in the same order, parts, objects and forces bit for bit."""
    from app.robot.simulation import _PART_BODIES

    scene = _scene(protocol_path, contacts="always")
    box = np.array(scene.object("box").position)
    a, b = box + np.array([0.0, 0.15, 0.03]), box + np.array([0.0, -0.08, 0.03])
    sweep = Trial(_config(protocol_path, scene, time_limit_s=6.0), Sweep(a, b, speed=0.1))
    cfg = trial_config_from_protocol(protocol_path, "easy-right", "timid")
    grasp = Trial(cfg, ScriptedInput(seed=3))
    pushed = held = 0
    for trial in (sweep, grasp):
        sim = trial.sim
        objects = {body: k for k, body in enumerate(trial.scene.object_body_ids)}
        parts = {sim.model.body(name).id: k for k, name in enumerate(_PART_BODIES)}
        while not trial.done:
            trial.tick()
            data, expected = sim.data, []
            for i in range(data.ncon):
                b1, b2 = (int(sim.model.geom_bodyid[g]) for g in data.contact.geom[i])
                if b1 in parts and b2 in objects:
                    part, obj = parts[b1], objects[b2]
                elif b2 in parts and b1 in objects:
                    part, obj = parts[b2], objects[b1]
                else:
                    continue
                adr = int(data.contact.efc_address[i])
                expected.append(
                    (part, obj, max(float(data.efc_force[adr]), 0.0) if adr >= 0 else 0.0)
                )
            got = sim.arm_contacts()
            assert got == expected and [f.hex() for *_, f in got] == [f.hex() for *_, f in expected]
            pushed += trial is sweep and any(f > 0.0 for *_, f in got)
            held += trial is grasp and len(got) >= 4
    assert pushed > 10 and held > 10, (pushed, held)  # the arm pushed the box, the fingers held it

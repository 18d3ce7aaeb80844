"""The paper's protocol states the robot's confidence at the start pose of every task (comments
under ``[confidence]`` in protocols/dragan2013.toml); these tests hold it to the trial's own
numbers, so the statement cannot rot when a scene, D or the prediction changes.

What a participant would notice: an aggressive robot that takes charge before they have moved
(the paper's robot is "wrong until the user makes his preference clear", its confidence rising
"as the user makes progress towards the predicted object"), or, in a Wrong task, one that never
takes charge toward the wrong object at all (then "aggressive and wrong" is not the situation).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from app.teleop.scripted import IdleInput
from app.trial.trial import Trial
from study.protocol import load_protocol
from tests.protocol_copies import PAPER_PROTOCOL

PROTOCOL = load_protocol(PAPER_PROTOCOL)
STATED = re.compile(r"(?m)^#\s+(.*\b\d\.\d\d\b.*)$")
PAIR = re.compile(r"\b([a-z]+-[a-z]+) (\d\.\d\d)\b")


def stated() -> dict[str, float]:
    """``{task: confidence}`` as the protocol's ``[confidence]`` comments state it."""
    text = PAPER_PROTOCOL.read_text(encoding="utf-8")
    section = text.split("\n[confidence]\n", 1)[1].split("\n[", 1)[0]
    pairs = [p for line in STATED.findall(section) for p in PAIR.findall(line)]
    out = {task: float(c) for task, c in pairs if task in PROTOCOL.task_names}
    assert len(out) == len([p for p in pairs if p[0] in PROTOCOL.task_names]), "stated twice"
    return out


def aggressive_threshold() -> float:
    (mode,) = [m for m in PROTOCOL.modes if dict(m.arbitration or {}).get("kind") == "aggressive"]
    return float(dict(mode.arbitration)["threshold"])


def started(task: str, mode: str = "aggressive") -> Trial:
    """A trial of ``task`` after its first tick, the user not having moved."""
    trial = Trial(PROTOCOL.trial_config(task, mode), IdleInput(), seed=0)
    trial.tick()
    return trial


def test_every_task_states_its_start_confidence() -> None:
    assert sorted(stated()) == sorted(PROTOCOL.task_names)


@pytest.mark.parametrize("task", PROTOCOL.task_names)
def test_the_stated_start_confidence_is_the_trials_and_no_mode_takes_charge(task: str) -> None:
    threshold = aggressive_threshold()
    for mode in ("aggressive", "timid"):
        trial = started(task, mode)
        first = trial.records[0]
        assert first.confidence == pytest.approx(stated()[task], abs=0.005), (task, mode)
        assert first.confidence < threshold
        if mode == "aggressive":
            assert first.alpha == 0.0  # the robot leaves the arm to the user until they move
        wrong = trial.scene.goals.names[first.predicted] != trial.scene.target
        assert wrong == (PROTOCOL.task(task).correctness == "wrong")  # wrong from the start


@pytest.mark.parametrize("task", [t for t in PROTOCOL.task_names if t.endswith("-wrong")])
def test_a_reach_over_the_table_makes_the_wrong_robot_take_charge(task: str) -> None:
    """The page's inputs move the gripper over the table first, then down: on that reach toward
    the box the aggressive robot, still predicting the bottle, takes charge before the input is
    nearer the box (the paper's wrong-yet-rectifiable situation)."""
    trial = started(task)
    names = trial.scene.goals.names
    target = np.asarray(trial.scene.goals.positions[names.index(trial.scene.target)])
    start = np.asarray(trial.scene.start_ee)[:3]
    over = np.array([target[0], target[1], start[2]])
    q = trial.scene.start_q
    took_charge = []
    for s in np.linspace(0.0, 1.0, 101):
        rec = trial.blender.step(q, q, x=start + s * (over - start))
        if names[rec.predicted] != trial.scene.target and rec.alpha > 0.0:
            took_charge.append(s)
    assert took_charge, "the aggressive robot never takes charge toward the wrong object"
    assert min(took_charge) > 0.0  # not at the start: only after the user has made progress

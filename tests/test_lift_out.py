"""The open hand leaves an object it is around upward before going elsewhere.

An aggressive robot that is wrong took the hand down around the bottle; when its confidence
dropped, the user's straight-line command swept a finger through the bottle and knocked it over
(14 knocks in 16 aggressive-and-wrong runs of 8 simulated participants, none elsewhere).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.blending import reach_below
from app.robot import build_scene
from app.teleop.keyboard import KEY_SPEED_M_S
from app.teleop.lift_out import CLEARANCE_M, MARGIN_M, lift_out
from app.teleop.types import TeleopCommand, TrialObservation
from app.trial import Trial
from app.trial.events import EventKind
from study.protocol import trial_config_from_protocol

BOTTLE = (0.55, -0.08, 0.02, 0.25)  # x, y, radius, top


def test_out_first_then_across_and_a_target_at_the_object_is_followed() -> None:
    kw = {"reach_below": 0.05, "slot": 0.04}
    floor = 0.25 + 0.05 + CLEARANCE_M
    inside = (0.55, -0.08, 0.17)
    up = (0.55, -0.08, floor + MARGIN_M)
    assert lift_out(inside, (0.64, 0.06, 0.25), [BOTTLE], **kw) == up  # far: out first
    # a key held away: the target leads the hand by 2 cm, still over the bottle
    assert lift_out(inside, (0.55, -0.06, 0.17), [BOTTLE], **kw) == up
    above = (0.55, -0.08, floor + 0.001)
    assert lift_out(above, (0.64, 0.06, 0.04), [BOTTLE], **kw) == (0.64, 0.06, floor)
    assert lift_out(inside, (0.64, 0.06, 0.04), [BOTTLE], **kw) == up  # aimed low: out first
    assert lift_out(inside, (0.56, -0.07, 0.10), [BOTTLE], **kw) is None  # at the bottle
    off_centre = (0.555, -0.09, 0.17)
    assert lift_out(off_centre, (0.552, -0.082, 0.17), [BOTTLE], **kw) is None  # centring on it
    assert lift_out((0.40, 0.0, 0.17), (0.64, 0.06, 0.04), [BOTTLE], **kw) is None  # not over it


class _AroundThenAway:
    """A user who takes the open hand down around ``first`` (from above it), then aims at
    ``then`` -- where an aggressive, wrong robot leaves the hand when its confidence drops."""

    def __init__(self, first: np.ndarray, then: np.ndarray) -> None:
        self.stages = [first + np.array((0.0, 0.0, 0.12)), first, then]
        self.stage = 0

    def command(self, obs: TrialObservation) -> TeleopCommand:
        goal = self.stages[self.stage]
        if self.stage < 2 and np.linalg.norm(obs.ee - goal) < 0.004:
            self.stage += 1
        return TeleopCommand(target=np.asarray(self.stages[self.stage], dtype=float))


class _AroundThenKeys(_AroundThenAway):
    """The same, but leaving as a held sideways key does on the page: the target slides
    sideways (along y, across the fingers' slot), at the hand's height, to ``then``'s y at the
    keys' speed, a couple of centimetres ahead of the hand."""

    def __init__(self, first: np.ndarray, then: np.ndarray) -> None:
        super().__init__(first, np.array((first[0], then[1], first[2])))  # A/D: along y

    def command(self, obs: TrialObservation) -> TeleopCommand:
        if self.stage < 2:
            cmd = super().command(obs)
            self.held = np.array(cmd.target, dtype=float)
            return cmd
        step = self.stages[2] - self.held
        dist = float(np.linalg.norm(step))
        if dist > 1e-9:
            self.held = self.held + step * min(1.0, KEY_SPEED_M_S / obs.rate_hz / dist)
        return TeleopCommand(target=self.held.copy())


@pytest.mark.parametrize("user", [_AroundThenAway, _AroundThenKeys])
def test_a_hand_around_the_wrong_object_rises_out_of_it_and_knocks_nothing(
    protocol_path, user
) -> None:
    cfg = dataclasses.replace(
        trial_config_from_protocol(protocol_path, "easy-right", "none"), time_limit_s=20.0
    )
    scene = build_scene(cfg.scene)
    k = scene.object_names.index("bottle")
    other = scene.target_index
    away = scene.goals.positions[other] + np.array((0.0, 0.0, 0.08))
    user = user(scene.goals.positions[k].copy(), away)
    trial = Trial(cfg, user, scene=scene)
    path = []
    while not trial.done and trial.t < 18.0:
        trial.tick()
        if user.stage == 2:
            path.append(trial.sim.ee.copy())
    assert path, "the hand never got around the bottle"
    path = np.array(path)
    assert trial.accidents.count == 0, "the bottle was knocked over or pushed"
    touched = [e for _, e in trial.events if e.kind is EventKind.CONTACT and e.obj == "bottle"]
    assert not touched, touched
    top = scene.goals.positions[k][2] + scene.goals.envelopes[k][1]
    sideways = np.linalg.norm(path[:, :2] - path[0, :2], axis=1)
    rose = path[np.argmax(sideways > 0.03)]  # where the hand was once 3 cm across
    fingertips = reach_below(scene.hand)  # below the TCP
    assert rose[2] - fingertips > top, "it moved across before its fingertips cleared the bottle"
    assert np.linalg.norm(path[-1] - user.stages[2]) < 0.01

"""A pause ends with the participant's input where they left it, not where the robot took the arm.

A participant testing the robot saw it (easy-wrong, aggressive, a reload mid-run): the robot had
taken the gripper onto the bottle while their handle was 15 cm away over the box; after the
pause their target had jumped onto the bottle, the prediction read the bottle with confidence
1.00, and they had to steer back. In the absolute mapping the handle is the participant's input
and a pause must not move it; in the relative one the handle goes back on the gripper.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.teleop import ParticipantInput
from app.trial import Trial
from study.protocol import trial_config_from_protocol
from study.server.live.controls import LiveInput


class Page:
    """What the live input asks of the participant's page: where the handle is drawn."""

    def __init__(self) -> None:
        self.handle: np.ndarray | None = None
        self.shown = True

    def move_gizmo(self, at: np.ndarray) -> None:
        self.handle = np.array(at, dtype=float)

    def show_gizmo(self, visible: bool) -> None:
        self.shown = visible


def _trial_with_input(protocol_path, mapping: str) -> tuple[Trial, ParticipantInput, LiveInput]:
    """easy-wrong / aggressive, 30 s, driven by a participant input behind a live input."""
    config = trial_config_from_protocol(protocol_path, "easy-wrong", "aggressive")
    source = ParticipantInput(mapping=mapping)
    trial = Trial(dataclasses.replace(config, time_limit_s=30), source)
    live = LiveInput(code="TEST01", record=lambda kind, detail: True)
    live.source = source
    return trial, source, live


def _paused_and_resumed(protocol_path, mapping: str) -> tuple[Trial, LiveInput, Page, dict]:
    """easy-wrong / aggressive: the participant's handle held over the box while the robot
    takes the gripper toward the bottle; then a pause (freeze) and its end (thaw)."""
    trial, source, live = _trial_with_input(protocol_path, mapping)
    goals, right = trial.scene.goals.positions, trial.scene.target_index
    start = trial.poses().gripper.copy()
    wanted = start + 0.5 * (goals[right] - start)  # halfway to the box, at the start height
    wanted[2] = start[2]
    for _ in range(400):
        if mapping == "absolute":
            source.set_target(wanted)  # the handle held there
        trial.tick()
    before = {
        "target": np.array(trial.user_target, float),
        "gripper": trial.poses().gripper.copy(),
        "decoy": goals[1 - right],
    }
    page = Page()
    live.freeze(page)  # a reload, the experimenter's pause, a control fault
    live.thaw(page, before["gripper"])
    trial.tick()
    live.close()
    return trial, live, page, before


def test_a_pause_leaves_the_absolute_target_where_the_participant_put_it(protocol_path) -> None:
    trial, _, page, before = _paused_and_resumed(protocol_path, "absolute")
    apart = float(np.linalg.norm(before["gripper"] - before["target"]))
    assert apart > 0.03, f"the robot did not take the gripper away from the target ({apart:.3f})"
    after = np.array(trial.user_target, float)
    assert np.allclose(after, before["target"], atol=1e-9), (
        f"the target moved {np.linalg.norm(after - before['target']):.3f} m over the pause"
    )
    assert page.shown and page.handle is not None
    assert np.allclose(page.handle, before["target"], atol=1e-9)  # drawn where they left it


def test_a_pause_puts_the_relative_handle_back_on_the_gripper(protocol_path) -> None:
    trial, _, page, before = _paused_and_resumed(protocol_path, "relative")
    assert page.shown and page.handle is not None
    assert np.allclose(page.handle, before["gripper"], atol=1e-9)
    # nothing pending: the first tick holds the gripper where it was
    assert float(np.linalg.norm(trial.user_target - before["gripper"])) == pytest.approx(
        0.0, abs=1e-3
    )


def test_a_pose_sent_just_before_the_pause_is_where_the_handle_is_drawn(protocol_path) -> None:
    """The handle's last pose arrived between two ticks and the pause came before the second:
    after the pause the page draws the handle where the next tick's target is, that pose."""
    trial, source, live = _trial_with_input(protocol_path, "absolute")
    start = trial.poses().gripper.copy()
    for _ in range(50):
        source.set_target(start)
        trial.tick()
    late = start + np.array([0.0, 0.03, 0.0])  # the drag's last pose, not yet used by a tick
    source.set_target(late)
    page = Page()
    live.freeze(page)
    live.thaw(page, trial.poses().gripper.copy())
    trial.tick()
    live.close()
    assert page.handle is not None
    assert np.allclose(trial.user_target, late, atol=1e-9)
    assert np.allclose(page.handle, trial.user_target, atol=1e-9), (
        f"the handle is drawn {np.linalg.norm(page.handle - trial.user_target) * 100:.1f} cm "
        "from the target the robot is steered to"
    )


def test_a_handle_let_go_past_the_reach_during_a_pause_comes_back_inside(protocol_path) -> None:
    """Let go past the reach during a pause (a hostile-client pass found the handle redrawn 15 cm
    outside the frame after the resume, the arm held at its edge): the resume draws it over the
    point the arm is sent to, as a release outside a pause does, and that is the target."""
    trial, source, live = _trial_with_input(protocol_path, "absolute")
    reach = trial.scene.reach
    start = trial.poses().gripper.copy()
    past = start + np.array([0.0, 0.6, 0.0])  # dragged far past the side of the frame
    assert not reach.contains(past)
    for _ in range(10):
        source.set_target(past)
        trial.tick()
    page = Page()
    live.freeze(page)
    live.thaw(page, trial.poses().gripper.copy(), reach=reach)
    trial.tick()
    live.close()
    assert page.handle is not None and reach.contains(page.handle, tol=1e-6)
    assert np.allclose(page.handle, reach.clamp(past), atol=1e-9)
    assert np.allclose(trial.user_target, page.handle, atol=1e-9)


def test_a_key_a_pause_let_go_of_is_not_recorded_as_expired(protocol_path) -> None:
    """W held through a pause moves nothing after it until pressed again; when the page then
    goes silent, no ``keys_expired`` event says the server let go of it (it moved nothing).
    A key the input still holds is recorded."""
    recorded: list[tuple[str, dict]] = []
    source = ParticipantInput(mapping="absolute")
    live = LiveInput(code="TEST01", record=lambda kind, detail: recorded.append((kind, detail)))
    live.source = source
    source.key_down("w")
    page = Page()
    live.freeze(page)
    live.thaw(page, np.array([0.5, 0.0, 0.3]))
    live.let_go(frozenset("w"))  # the page's last state said W; the pause had let go of it
    source.key_down("d")
    live.let_go(frozenset("d"))
    live.close()
    assert recorded == [("keys_expired", {"keys": "d"})]

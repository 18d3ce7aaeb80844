"""The participant's gizmo and keys combine into one input source without fighting."""

from __future__ import annotations

import numpy as np
import pytest

from app.teleop import ReachRegion, TrialObservation
from app.teleop.errors import InvalidTargetError
from app.teleop.participant_input import InputFrozen, ParticipantInput
from study.protocol import LikertItem, Scale
from study.server.page_inputs import (
    InputRejected,
    parse_answer,
    parse_key_state,
    parse_position,
)

REACH = ReachRegion(np.array([0.2, -0.5, 0.0]), np.array([0.75, 0.5, 0.6]))


def _obs(user_target: np.ndarray) -> TrialObservation:
    return TrialObservation(
        t=0.0,
        q=np.zeros(7),
        ee=user_target.copy(),
        gripper_closed=False,
        user_target=user_target,
        reach=REACH,
        goal_names=("a", "b"),
        goal_positions=np.zeros((2, 3)),
        target_index=0,
    )


def test_gizmo_pose_wins_then_keys_move_from_the_clamped_target() -> None:
    src = ParticipantInput(start_target=np.array([0.4, 0.0, 0.3]), key_speed_m_s=0.1)
    src.set_target(np.array([0.5, 0.1, 0.9]))  # above the reach: the trial clamps it
    cmd = src.command(_obs(np.array([0.4, 0.0, 0.3])))
    assert np.allclose(cmd.target, [0.5, 0.1, 0.9]) and len(src.latencies_s) == 1
    src.key_down("f")
    cmd = src.command(_obs(np.array([0.5, 0.1, 0.6])))
    assert np.allclose(cmd.target, [0.5, 0.1, 0.599])  # from the clamped 0.6, not from 0.9
    assert src.key_moved.is_set() and np.allclose(src.gizmo.target, [0.5, 0.1, 0.599])
    src.key_up("f")  # held 10 ms: topped up to a tap (80 ms at 0.1 m/s)
    cmd = src.command(_obs(np.array([0.5, 0.1, 0.599])))
    assert np.allclose(cmd.target, [0.5, 0.1, 0.592])
    cmd = src.command(_obs(np.array([0.5, 0.1, 0.592])))  # nothing new: the target holds
    assert np.allclose(cmd.target, [0.5, 0.1, 0.592]) and not cmd.grasp


def test_a_frozen_input_refuses_everything_and_applies_nothing_later() -> None:
    src = ParticipantInput(start_target=np.array([0.4, 0.0, 0.3]))
    here = np.array([0.4, 0.0, 0.3])
    src.key_down("r")
    src.request_grasp()
    src.freeze()  # the experimenter pauses with R held and a grasp pending
    for call in (
        lambda: src.key_down("r"),
        lambda: src.set_target(np.array([0.5, 0.0, 0.3])),
        src.request_grasp,
    ):
        with pytest.raises(InputFrozen):
            call()
    src.key_up("r")  # released during the pause: fine, nothing owed
    src.thaw()
    cmd = src.command(_obs(here))
    assert np.allclose(cmd.target, here) and not cmd.grasp


def test_grasp_request_lasts_one_tick() -> None:
    src = ParticipantInput(start_target=np.array([0.4, 0.0, 0.3]))
    src.request_grasp()
    assert src.command(_obs(np.array([0.4, 0.0, 0.3]))).grasp
    assert not src.command(_obs(np.array([0.4, 0.0, 0.3]))).grasp


def test_bad_gizmo_pose_is_refused_and_changes_nothing() -> None:
    src = ParticipantInput(start_target=np.array([0.4, 0.0, 0.3]))
    with pytest.raises(InvalidTargetError):
        src.set_target(np.array([np.nan, 0.0, 0.3]))
    assert np.allclose(src.gizmo.target, [0.4, 0.0, 0.3]) and len(src.latencies_s) == 0
    with pytest.raises(InputRejected, match="finite"):
        parse_position((0.1, float("inf"), 0.2))
    with pytest.raises(InputRejected):
        parse_position((0.1, 0.2))


def test_answers_must_be_on_the_scale() -> None:
    assert parse_answer("7", points=7) == 7
    for bad in ("8", "0", "-1", "4.5", "x", ""):
        with pytest.raises(InputRejected):
            parse_answer(bad, points=7)
    item = LikertItem(
        "helpful", "How helpful?", Scale("agree7", tuple(f"a{k}" for k in range(1, 8)))
    )
    assert item.points == 7 and item.anchor_text() == "1 = a1 · 4 = a4 · 7 = a7"


def test_key_states_are_ascii_number_and_known_letters() -> None:
    assert parse_key_state("12 ar") == (12, frozenset("ar"))
    assert parse_key_state("3 ") == (3, frozenset())
    for bad in ("² w", "٣ w", "12 az", "12", "-1 w", "1" * 40 + " w", "12  w"):
        with pytest.raises(InputRejected):
            parse_key_state(bad)

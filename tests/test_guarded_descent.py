"""The open hand comes down over an object only where the object fits between its fingers.

A new participant lowered the open gripper beside the practice mug's axis: a fingertip landed
on the rim, the hand hopped on it several times a second and the mug went over (headless: the
mug knocked or pushed at every offset from 2.5 to 4.5 cm across the slot). Now the hand stops
just clear of the top, follows the target sideways, says so (``Trial.held_above``), and comes
down once the mug fits between the fingers.
"""

from __future__ import annotations

import pytest

from app.teleop.guarded_descent import guard_descent
from benchmarks.rim_descent import run

MUG = (0.5, -0.25, 0.028, 0.12, 0.028)  # x, y, radius, top, half-width across the slot
KW = {"reach_below": 0.05, "slot": 0.04}
FLOOR = 0.12 + 0.05 + 0.01  # top + fingertips + clearance


def test_the_hand_is_held_just_clear_of_the_top_until_the_object_fits_between_the_fingers() -> None:
    above = (0.5, -0.22, 0.25)  # 3 cm off the axis across the slot, fingertips 8 cm over the top
    low_beside = (0.5, -0.22, 0.05)
    assert guard_descent(above, low_beside, [MUG], **KW) == ((0.5, -0.22, FLOOR), 0)
    on_rim = (0.5, -0.22, 0.12 + 0.05)  # fingertips on the top
    assert guard_descent(on_rim, low_beside, [MUG], **KW) is not None
    centred = (0.5, -0.255, 0.05)  # the mug fits between the fingers (5 mm off)
    assert guard_descent(above, centred, [MUG], **KW) is not None  # the hand is not there yet
    assert guard_descent((0.5, -0.252, 0.25), centred, [MUG], **KW) is None  # it is: down
    beside = (0.56, -0.22, 0.05)  # the mug is beside the fingers' pads, along x
    assert guard_descent((0.56, -0.22, 0.25), beside, [MUG], **KW) is None
    around = (0.5, -0.23, 0.12 + 0.05 - 0.02)  # fingertips already below the top
    assert guard_descent(around, low_beside, [MUG], **KW) is None  # lift_out's business
    assert guard_descent(above, (0.5, -0.22, 0.20), [MUG], **KW) is None  # not asked down
    assert guard_descent(above, low_beside, [MUG], **KW, skip=(0,)) is None  # the robot's goal
    assert guard_descent((0.3, 0.0, 0.25), low_beside, [MUG], **KW) is None  # not over it


@pytest.mark.parametrize("offset_m", [0.025, 0.035])
def test_lowering_beside_the_practice_mug_leaves_it_standing(offset_m: float) -> None:
    row = run(offset_m, axis=1, seconds=6.0)
    assert row["knocked_or_pushed"] == 0 and row["contacts"] == 0, row
    assert row["hand_z_range_m"] < 0.002, row  # held still above it, no hopping


def test_lowered_over_the_mug_the_hand_still_goes_down_around_it() -> None:
    held = run(0.035, axis=1, seconds=6.0)
    row = run(0.01, axis=1, seconds=6.0)  # 1 cm off: the mug fits between the fingers
    assert row["knocked_or_pushed"] == 0 and row["object_moved_m"] < 0.005, row
    assert row["hand_z_end_m"] < held["hand_z_end_m"] - 0.05, (row, held)  # around it

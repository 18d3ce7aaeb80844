"""The open hand comes down over an object only where the object fits between its fingers.

A new participant lowered the open gripper beside the practice mug's axis: a fingertip landed
on the rim, the hand hopped on it several times a second and the mug went over (headless: the
mug knocked or pushed at every offset from 2.5 to 4.5 cm across the slot). Now the hand stops
just clear of the top, follows the target sideways, says so (``Trial.held_above``), and comes
down once the mug fits between the fingers.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from app.teleop.guarded_descent import HOVER_M, PALM_CLEAR_M, SETTLE_S, DescentGuard
from app.teleop.scripted import IdleInput
from app.trial import Trial
from benchmarks.rim_descent import run
from study.protocol import load_protocol

MUG = (0.5, -0.25, 0.028, 0.12, 0.028)  # x, y, radius, top, half-width across the slot
FLOOR = 0.12 + 0.05 + 0.01  # top + fingertips + clearance
HOLD = FLOOR + HOVER_M
LOW_BESIDE = (0.5, -0.22, 0.05)  # 3 cm off the axis across the slot, below the top


def _guard() -> DescentGuard:
    return DescentGuard(reach_below=0.05, slot=0.04, palm_above=0.0374)


def _takes(x, target, **kw) -> tuple | None:
    """What a fresh guard steers to (it holds nothing yet)."""
    return _guard().steer(x, target, [MUG], now=0.0, **kw)


def test_the_hand_is_held_just_clear_of_the_top_until_the_object_fits_between_the_fingers() -> None:
    above = (0.5, -0.22, 0.25)  # 3 cm off the axis across the slot, fingertips 8 cm over the top
    assert _takes(above, LOW_BESIDE) == (0.5, -0.22, HOLD)
    on_rim = (0.5, -0.22, 0.12 + 0.05)  # fingertips on the top
    assert _takes(on_rim, LOW_BESIDE) is not None
    centred = (0.5, -0.255, 0.05)  # the mug fits between the fingers (5 mm off)
    assert _takes(above, centred) is not None  # the hand is not there yet
    assert _takes((0.5, -0.252, 0.25), centred) is None  # it is: down
    beside = (0.56, -0.22, 0.05)  # the mug is beside the fingers' pads, along x
    assert _takes((0.56, -0.22, 0.25), beside) is None
    around = (0.5, -0.23, 0.12 + 0.05 - 0.02)  # fingertips already below the top
    assert _takes(around, LOW_BESIDE) is None  # lift_out's business
    assert _takes(above, (0.5, -0.22, 0.20)) is None  # not asked down
    assert _takes(above, LOW_BESIDE, skip=(0,)) is None  # the robot's goal
    assert _takes((0.3, 0.0, 0.25), LOW_BESIDE) is None  # not over it


def test_a_hold_outlasts_noise_and_a_sagging_hand_and_lets_go_once_both_are_centred() -> None:
    guard = _guard()
    assert guard.steer((0.5, -0.22, 0.25), LOW_BESIDE, [MUG], now=0.0) is not None
    # the hand sags onto the rim (a fresh guard would leave it to lift_out): still held
    sagged = (0.5, -0.235, 0.12 + 0.05 - 0.01)
    assert _takes(sagged, LOW_BESIDE) is None
    assert guard.steer(sagged, LOW_BESIDE, [MUG], now=0.1) == (0.5, -0.22, HOLD)
    # hand and target centred, but a noisy target leaves the fit now and then: still held
    centred, off = (0.5, -0.245, 0.05), (0.5, -0.236, 0.05)
    hand = (0.5, -0.246, 0.2)
    for i, target in enumerate([centred, off, centred, off, centred]):
        assert guard.steer(hand, target, [MUG], now=0.1 + 0.04 * i) is not None
    # a hand sweeping across the fit (a fast drag) is not let down on its way
    for i in range(6):
        sweep = (0.5, -0.262 + 0.004 * i, 0.2)
        assert guard.steer(sweep, centred, [MUG], now=0.3 + 0.05 * i) is not None
    # centred for SETTLE_S, the hand settled: let go, and it comes down around the mug
    assert guard.steer(hand, centred, [MUG], now=0.6) is not None
    assert guard.steer(hand, centred, [MUG], now=0.6 + SETTLE_S - 0.01) is not None
    assert guard.steer(hand, centred, [MUG], now=0.6 + SETTLE_S + 0.01) is None
    assert guard.held is None
    # coming down, the noisy target just off the fit does not take it again; clearly off does
    lower = (0.5, -0.246, 0.19)
    assert guard.steer(lower, off, [MUG], now=0.9) is None
    assert guard.steer(lower, (0.5, -0.232, 0.05), [MUG], now=0.91) is not None
    # a target raised to the top's height, a hand gone from over the mug, the robot's goal
    for hand, target, skip in (
        ((0.5, -0.22, 0.2), (0.5, -0.22, FLOOR), ()),
        ((0.5, -0.15, 0.2), LOW_BESIDE, ()),
        ((0.5, -0.22, 0.2), LOW_BESIDE, (0,)),
    ):
        guard = _guard()
        guard.steer((0.5, -0.22, 0.25), LOW_BESIDE, [MUG], now=0.0)
        assert guard.steer(hand, target, [MUG], now=0.01, skip=skip) is None
        assert guard.held is None


def test_lowered_around_the_mug_the_palm_stops_clear_of_its_top() -> None:
    guard = _guard()
    rest = 0.12 - 0.0374 + PALM_CLEAR_M  # the top, less the palm's height over the TCP
    centred, floor = (0.5, -0.25, 0.09), (0.5, -0.251, 0.02)  # F held to the reach's floor
    assert guard.rest(centred, floor, [MUG]) == ((0.5, -0.251, rest), 0)
    assert guard.rest(centred, (0.5, -0.251, rest + 0.001), [MUG]) is None  # not asked lower
    assert guard.rest((0.5, -0.22, 0.2), floor, [MUG]) is None  # on the rim: the hold's case
    assert guard.rest((0.545, -0.25, 0.09), floor, [MUG]) is None  # beside the finger pads
    assert guard.rest(centred, floor, [MUG], skip=(0,)) is None  # the robot's goal


def test_beside_the_mug_the_palm_stops_clear_of_its_top_where_it_overlaps_it() -> None:
    """Beside the finger pads (no longer around the mug) the palm, 3.2 cm to each side along
    the slot and 10.2 cm across it, still covers the mug's rim until 6 cm off its axis."""
    guard = DescentGuard(reach_below=0.05, slot=0.04, palm_above=0.0374, palm_half=(0.032, 0.102))
    rest = 0.12 - 0.0374 + PALM_CLEAR_M
    floor = (0.55, -0.25, 0.02)
    assert guard.around((0.55, -0.25, 0.09), [MUG]) is None  # the fingers pass beside it
    assert guard.under_palm((0.55, -0.25, 0.09), [MUG]) == 0
    assert guard.rest((0.55, -0.25, 0.09), floor, [MUG]) == ((0.55, -0.25, rest), 0)
    assert guard.rest((0.561, -0.25, 0.09), floor, [MUG]) is None  # the palm clears it
    assert guard.rest((0.5, -0.25 + 0.135, 0.09), floor, [MUG]) is None  # across, clear
    assert guard.rest((0.55, -0.25, 0.09), floor, [MUG], skip=(0,)) is None  # the robot's goal


def test_a_hand_let_go_of_at_the_palms_edge_is_taken_again_only_well_inside() -> None:
    """The footprint ends 6 cm off the mug's axis along the slot (2.8 + 3.2 cm). A hand the stop
    held there and let go of as it swayed out is not taken again for swaying 2 mm back in (a
    tester's hand bobbed 3 cm twice a second there); 4 mm in, it is. A hand the stop never held
    is taken at the footprint itself, as before, and so is one that has left it by 4 mm, and
    one beside an object so tall that the arm above the palm may meet it."""
    palm = {"reach_below": 0.05, "slot": 0.04, "palm_above": 0.0374, "palm_half": (0.032, 0.102)}
    guard = DescentGuard(**palm, low=0.13)  # the mug's top, 0.12, is under the arm
    rest = 0.12 - 0.0374 + PALM_CLEAR_M
    edge = 0.5 + 0.028 + 0.032

    def at(dx: float, z: float = rest, g: DescentGuard = guard) -> tuple | None:
        return g.rest((edge + dx, -0.25, z), (edge + dx, -0.25, 0.02), [MUG])

    assert at(-0.001) == ((edge - 0.001, -0.25, rest), 0)  # held 1 mm inside
    assert at(0.001) is None  # out: let go
    assert at(-0.002, z=rest - 0.02) is None  # 2 mm back in, coming down: left to come down
    assert at(-0.0015, z=0.02) is None and at(0.0005, z=0.02) is None  # on the table, swaying
    assert at(-0.004, z=0.02) == ((edge - 0.004, -0.25, rest), 0)  # well inside: held again
    assert at(-0.001) is not None  # ... until it leaves the footprint itself
    assert at(0.004) is None  # clear of it
    assert at(-0.001, z=0.02) == ((edge - 0.001, -0.25, rest), 0)  # taken at the footprint
    guard.release()  # the gripper closed: the stop holds nothing
    assert guard.palm_on is None and guard.palm_left is None
    fresh = DescentGuard(**palm, low=0.13)
    assert at(-0.002, z=0.02, g=fresh) == ((edge - 0.002, -0.25, rest), 0)  # never held: taken
    tall = DescentGuard(**palm, low=0.11)  # the arm above the palm comes down to the top
    assert at(-0.001, g=tall) is not None and at(0.001, g=tall) is None
    assert at(-0.002, z=rest - 0.02, g=tall) == ((edge - 0.002, -0.25, rest), 0)  # as before


def test_the_wrist_stops_the_hand_beside_an_object_taller_than_it_comes_down_to() -> None:
    """Beside the 20-cm bottle the palm's footprint ends 6.2 cm off its axis along the slot
    (3 + 3.2 cm); the wrist's part, 10.4 cm above the TCP and 4.4 cm to each side along the slot,
    reaches 7.4 cm. Between, the hand is stopped with the wrist just clear of the top (the
    palm's box alone let it come down on the bottle and knock it over); beyond, and over the
    robot's goal, it is not; the stop's hysteresis at the footprint holds for the wrist too."""
    bottle = (0.55, -0.08, 0.03, 0.2, 0.03)
    palm = {"reach_below": 0.05, "slot": 0.04, "palm_above": 0.0374, "palm_half": (0.032, 0.102)}
    guard = DescentGuard(**palm, parts=((0.1036, 0.044, 0.088),), low=0.124)
    wrist = 0.2 - 0.1036 + PALM_CLEAR_M

    def at(dx: float, z: float = 0.02, g: DescentGuard = guard, **kw) -> tuple | None:
        return g.rest((0.55 + dx, -0.08, 0.15), (0.55 + dx, -0.08, z), [bottle], **kw)

    assert at(-0.063) == ((0.55 - 0.063, -0.08, wrist), 0)
    assert at(0.07) == ((0.55 + 0.07, -0.08, wrist), 0)
    assert at(0.07, z=wrist + 0.001) is None  # the target above the stop
    assert at(0.075) is None and at(-0.075) is None  # beyond the wrist's footprint
    assert at(0.07, skip=(0,)) is None  # the robot's goal
    palm_stop = 0.2 - 0.0374 + PALM_CLEAR_M
    assert at(0.06) == ((0.55 + 0.06, -0.08, palm_stop), 0)  # under the palm: its stop
    assert at(0.063, g=DescentGuard(**palm, low=0.124)) is None  # the palm's box alone


def _shipped_trials() -> Iterator[tuple[Path, Trial]]:
    """A trial of every scene of every shipped protocol (its practice and each task, the first
    mode), with the protocol's path."""
    for path in sorted(Path("protocols").glob("*.toml")):
        if path.name == "population.toml":
            continue
        protocol = load_protocol(path)
        configs = [protocol.training_config()] + [
            protocol.trial_config(task, protocol.mode_names[0]) for task in protocol.task_names
        ]
        for config in configs:
            yield path, Trial(config, IdleInput(), keep_records=False)


def test_no_part_of_the_hand_stops_it_above_any_shipped_grasp_point() -> None:
    """At every object's grasp point in every shipped protocol's scenes, the input pressed to
    the reach's floor, the stop (the palm over the object, every part of the hand over every
    object) lies under the grasp point: the hand always reaches the grasp, the user alone or
    the robot taking it there."""
    for path, trial in _shipped_trials():
        floor = float(trial.scene.reach.lo[2])
        for k, g in enumerate(trial._grasp_points.tolist()):
            for skip in ((), (k,)):
                trial.guard.release()
                rest = trial.guard.rest(
                    g, (g[0], g[1], floor), trial.steering.footprints, skip=skip
                )
                assert rest is None or rest[0][2] < g[2] - 0.001, (path.name, k, skip, rest)


def test_the_palm_stops_above_every_shipped_grasp_point() -> None:
    """The palm's stop lies under every grasp point of every shipped protocol's scenes: the
    hand always reaches the grasp."""
    for path, trial in _shipped_trials():
        palm = trial.guard.palm_above
        for (_, _, _, top, _), g in zip(
            trial.steering.footprints, trial._grasp_points, strict=True
        ):
            assert top - palm + PALM_CLEAR_M < g[2] - 0.001, (path.name, top, g)


def test_a_hand_centred_on_any_shipped_object_has_no_other_object_under_its_palm() -> None:
    """The palm's stop beside an object never keeps the hand from a grasp: in every shipped
    protocol's scenes, the palm of a hand centred on one object clears every other one."""
    for path, trial in _shipped_trials():
        for k, (ox, oy, _, top, _) in enumerate(trial.steering.footprints):
            hand = (ox, oy, top + 0.05)
            assert trial.guard.under_palm(hand, trial.steering.footprints, skip=(k,)) is None, (
                path.name,
                k,
            )


@pytest.mark.parametrize("offset_m", [0.025, 0.035])
def test_lowering_beside_the_practice_mug_leaves_it_standing(offset_m: float) -> None:
    row = run(offset_m, axis=1, seconds=6.0)
    assert row["knocked_or_pushed"] == 0 and row["contacts"] == 0, row
    assert row["hand_z_range_m"] < 0.002, row  # held still above it, no hopping


def test_lowered_over_the_mug_the_hand_still_goes_down_around_it() -> None:
    held = run(0.035, axis=1, seconds=6.0)
    row = run(0.01, axis=1, seconds=6.0)  # 1 cm off: the mug fits between the fingers
    assert row["knocked_or_pushed"] == 0 and row["object_moved_m"] < 0.005, row
    assert row["contacts"] == 0, row  # the palm stops clear of the top (it landed on it)
    assert row["hand_z_end_m"] < held["hand_z_end_m"] - 0.05, (row, held)  # around it

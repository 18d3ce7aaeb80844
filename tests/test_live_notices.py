"""The trial screen's held notices, a missed grasp the participant can see, a finger on a rim.

``HeldNotices`` picks the one notice to hold: a resting finger first, then the reach, then a
missed grasp (for ``MISSED_NOTICE_S``, or until the next grasp request). After a miss the
gripper stays closed on nothing for ``MISSED_HOLD_S`` before it opens. ``ResistedDescent``
sees the gripper held up by a mug's rim in the practice scene (the tester's "frozen" gripper),
and not a gripper lowered around the mug and closed on it. Every notice passes every shipped
protocol's blinding check.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.teleop.guarded_descent import CENTRED_M
from app.teleop.types import TeleopCommand, TrialObservation
from app.trial import Trial
from app.trial.contacts import FINGERS
from app.trial.events import EventKind, TrialEvent
from app.trial.tasks.lift import CLOSE_S, MISSED_HOLD_S, REOPEN_S
from study.protocol import load_protocol
from study.server.blinding_guard import check_text
from study.server.live import texts
from study.server.live.notices import (
    LIMIT_HOLD_S,
    MISSED_NOTICE_S,
    PUT_BACK_S,
    HeldNotices,
    ResistedDescent,
)
from study.server.participant_page import GRASP_LABEL, GRIPPER_CLOSED_LABEL
from tests.protocol_copies import PAPER_PROTOCOL, STUDY_PROTOCOLS

MUG = np.array([0.5, -0.25, 0.07])
"""The practice scene's mug: its grasp point (the TCP 3 cm below its top)."""
BACK_SLIP = texts.SLIPPED_OFF_CENTRE.format(way="back (S)")
"""The slip said of a hand beyond the object's middle along x (S takes it back)."""
BACK_NOT_CENTRED = texts.not_centred(0.03, centred_m=CENTRED_M)
"""The "not in the middle" notice of a resting hand 3 cm beyond the middle along x."""


def test_a_missed_grasp_notice_stays_until_its_time_or_the_next_grasp() -> None:
    n = HeldNotices()
    assert n.text(100.0, live=True) is None
    n.missed = 100.0
    assert n.text(100.0, live=True) == texts.MISSED_GRASP
    assert n.text(100.0 + MISSED_NOTICE_S - 0.1, live=True) == texts.MISSED_GRASP
    assert n.text(100.0 + MISSED_NOTICE_S + 0.1, live=True) is None
    assert n.text(101.0, live=False) is None  # a paused or ended run holds nothing
    n.asked = 102.0  # the next grasp request takes it down
    assert n.text(102.0, live=True) is None
    n.missed = 103.0  # ... and the next miss puts it up again
    assert n.text(103.5, live=True) == texts.MISSED_GRASP
    n.forget()
    assert n.text(103.5, live=True) is None


def test_a_slipped_object_is_said_until_the_next_grasp() -> None:
    n = HeldNotices(slipped=20.0, missed=19.0)
    assert n.text(20.1, live=True) == texts.SLIPPED_OUT
    assert n.text(20.0 + MISSED_NOTICE_S + 0.1, live=True) is None
    n.asked = 21.0
    assert n.text(21.1, live=True) is None


def test_what_the_input_does_now_comes_first() -> None:
    n = HeldNotices(missed=10.0, resting=10.0, at_limit=10.0, fallen=10.0)
    assert n.text(10.1, live=True) == texts.FELL_OVER  # nothing else, until it stands again
    n = HeldNotices(above=10.0, lowest=10.0, at_limit=10.0, dropped=10.0, slipped=9.0)
    assert n.text(10.1, live=True) == texts.SLIPPED_WAITING  # ... nor until a dropped one is back
    n = HeldNotices(slipped=10.0, missed=9.0)  # a slip, the hand sinking back off-centre:
    n.lowest = n.off_centre = 11.0  # the slip is said first, until its time is up
    assert n.text(11.1, live=True) == texts.SLIPPED_OUT
    n.lowest = n.off_centre = 10.0 + MISSED_NOTICE_S
    assert n.text(10.1 + MISSED_NOTICE_S, live=True) == texts.NOT_CENTRED
    n = HeldNotices(missed=10.0, resting=10.0, at_limit=10.0)
    assert n.text(10.1, live=True) == texts.RESTING_ON_OBJECT  # F held onto a rim: both
    n = HeldNotices(missed=10.0, at_limit=10.0, above=10.0)
    assert n.text(10.1, live=True) == texts.HELD_ABOVE  # F held over an object's rim
    n = HeldNotices(missed=10.0, at_limit=10.0, lowest=10.0)
    assert n.text(10.1, live=True) == texts.AS_LOW_AS_IT_GOES  # F held down around an object
    n.off_centre = n.lowest = 10.2  # ... off its middle along the fingers
    assert n.text(10.3, live=True) == texts.NOT_CENTRED
    n.lowest = 10.4  # centred again
    assert n.text(10.5, live=True) == texts.AS_LOW_AS_IT_GOES
    n = HeldNotices(missed=10.0, at_limit=10.0)
    assert n.text(10.1, live=True) == texts.AT_REACH_LIMIT
    assert n.text(10.0 + LIMIT_HOLD_S + 0.1, live=True) == texts.MISSED_GRASP


def test_a_slip_says_why_and_a_wait_only_when_the_object_waits() -> None:
    """h11 (a new participant in Chromium, 8 slips 3 cm off along the slot): the mug was back
    0.2-0.6 s after the notice came up, which went on saying it would be put back "once the
    gripper is out of the way", in 34 words, and not why it slipped."""
    n = HeldNotices()
    n.lowest = n.off_centre = 10.0  # F held down off the mug's middle: "not in the middle"
    assert n.text(10.05, live=True) == texts.NOT_CENTRED
    n.ask(10.1, offset=0.03)  # G: the notice about the open hand goes with the request
    assert n.text(10.2, live=True) is None
    n.slipped = n.dropped = 10.9  # lifted, slipped out, standing: put back 0.3-0.7 s later
    assert n.text(11.0, live=True) == BACK_SLIP  # why, and the key that mends it
    n.dropped = 11.5  # back at 11.5; the hand sinks back off-centre
    n.lowest = n.off_centre = 12.0
    assert n.text(12.0, live=True) == BACK_SLIP  # said first, for its time
    n.lowest = n.off_centre = 10.9 + MISSED_NOTICE_S
    assert n.text(10.9 + MISSED_NOTICE_S + 0.1, live=True) == texts.NOT_CENTRED
    n.off_by = 0.03  # the resting hand's offset known: the same one key as the slip said
    assert n.text(10.9 + MISSED_NOTICE_S + 0.1, live=True) == BACK_NOT_CENTRED
    assert "(W/S)" not in BACK_NOT_CENTRED and "back (S)" in BACK_NOT_CENTRED
    n = HeldNotices()  # h14: S pressed as the slip said, the hand centred 2.7 s after G
    n.ask(40.0, offset=0.03)
    n.slipped, n.lowest, n.off_centre = 41.0, 41.5, 41.5
    assert n.text(41.6, live=True) == BACK_SLIP
    n.lowest = n.centred = 42.7  # resting centred now: the notice that invites G, not "back"
    assert n.text(42.8, live=True) == texts.AS_LOW_AS_IT_GOES
    n.lowest = n.off_centre = 43.2  # h15: held S too long, overshot 3 cm: the other key now
    n.off_by = -0.03
    assert n.text(43.3, live=True) == texts.not_centred(-0.03, centred_m=CENTRED_M)
    assert "away (W)" in n.text(43.3, live=True)
    assert n.text(44.0, live=True) is None  # moving: nothing, never the slip's "back (S)" again
    n = HeldNotices()  # G with the hand centred; the object still slips out, and waits
    n.ask(20.1, offset=0.0)
    n.slipped = n.dropped = 21.0
    assert n.text(21.5, live=True) == texts.SLIPPED_OUT
    n.dropped = 21.75  # back 0.75 s after the slip: no "waiting" said on the way (h13 saw it)
    assert n.text(21.9, live=True) == texts.SLIPPED_OUT
    n.dropped = 21.0 + PUT_BACK_S  # still down a second on: the gripper is in its spot
    assert n.text(21.0 + PUT_BACK_S, live=True) == texts.SLIPPED_WAITING
    n = HeldNotices(at_limit=25.0, lowest=25.0)  # F held at the stop (past the reach's floor)
    n.ask(25.05, offset=0.0)  # ... as G is pressed: neither notice over the closing fingers
    assert n.text(25.1, live=True) is None
    n = HeldNotices(lowest=30.0, off_centre=30.0)  # a miss off-centre: said first, and why
    n.ask(30.1, offset=-0.035)
    n.missed = 31.0
    n.lowest = n.off_centre = 31.6  # the hand opens where it was
    assert n.text(31.7, live=True) == texts.MISSED_OFF_CENTRE.format(way="away (W)")
    for text in (
        texts.SLIPPED_OUT,
        BACK_SLIP,
        texts.SLIPPED_WAITING,
        texts.MISSED_OFF_CENTRE.format(way="away (W)"),
    ):
        assert len(text.split()) <= 24, text  # read in the 5 s it is said first


@pytest.mark.parametrize("dx", [0.031, 0.036])
def test_g_pressed_off_the_middle_takes_the_open_hands_notice_down_and_says_why(
    dx: float,
) -> None:
    """h12 in Chromium: "... not in the middle ... then press G" stayed over the closing,
    lifting and reopening fingers after every G (the trial's note of the resting hand was the
    last reach tick's), outranked "closed on nothing" for good after a miss, and the reach
    notice flashed with F still held. F held down 3.1 / 3.6 cm off the mug's middle along the
    slot, then G, the notices fed as the live run feeds them: before G "not in the middle";
    while the task drives the gripper no notice of the open hand or the reach; then why the
    grasp failed, first."""
    trial = _practice(_Keys((dx, 0.0), floor=0.02, grasp_t=5.0))
    notices, shown = HeldNotices(), []
    while trial.t < 9.0 and not trial.done:
        rec = trial.tick()
        clamped = TrialEvent(EventKind.TARGET_CLAMPED) in rec.events
        notices.note_tick(trial, rec.events, rec.t, past_reach=clamped)
        shown.append((rec.t, trial.task.reaching, notices.text(rec.t, live=True)))
    before = [text for t, _, text in shown if 4.8 < t < 5.0]
    assert set(before) == {BACK_NOT_CENTRED}, set(before)  # the one key that mends it
    assert trial.grasp_offset > 0.0  # beyond the middle: S takes it back
    driven = {text for t, reaching, text in shown if t >= 5.0 and not reaching}
    open_hand = {BACK_NOT_CENTRED, texts.NOT_CENTRED, texts.AS_LOW_AS_IT_GOES, texts.HELD_ABOVE}
    assert not driven & (open_hand | {texts.AT_REACH_LIMIT}), driven
    failed = [text for t, _, text in shown if t > 5.0 and text not in (None, *open_hand)]
    why = (texts.MISSED_OFF_CENTRE, texts.SLIPPED_OFF_CENTRE)
    assert failed and failed[0] in [w.format(way="back (S)") for w in why], failed
    assert trial.resting_on is None or trial.task.reaching


@pytest.mark.parametrize("path", STUDY_PROTOCOLS, ids=lambda p: p.stem)
def test_the_notices_name_no_condition(path) -> None:
    words = load_protocol(path).condition_words
    for text in (
        texts.MISSED_GRASP,
        texts.MISSED_OFF_CENTRE.format(way=texts.toward_middle(0.03)),
        texts.MISSED_OFF_CENTRE.format(way=texts.toward_middle(-0.03)),
        texts.RESTING_ON_OBJECT,
        texts.HELD_ABOVE,
        texts.AS_LOW_AS_IT_GOES,
        texts.FELL_OVER,
        texts.SLIPPED_OUT,
        BACK_SLIP,
        texts.SLIPPED_OFF_CENTRE.format(way=texts.toward_middle(-0.03)),
        texts.SLIPPED_WAITING,
        texts.NOT_CENTRED,
        BACK_NOT_CENTRED,
        texts.not_centred(-0.03, centred_m=CENTRED_M),
        texts.AT_REACH_LIMIT,
        GRASP_LABEL,
        GRIPPER_CLOSED_LABEL,
    ):
        check_text(text, words=words)


class _Keys:
    """A participant with keys: over ``(MUG + offset)`` at 15 cm, then F held from 2.5 s (the
    target falls at 0.1 m/s to ``floor``); G at ``grasp_t``."""

    def __init__(self, offset: tuple[float, float], floor: float, grasp_t: float = 1e9) -> None:
        self.offset, self.floor, self.grasp_t = offset, floor, grasp_t

    def command(self, obs: TrialObservation) -> TeleopCommand:
        z = 0.15 if obs.t < 2.5 else max(self.floor, 0.15 - 0.1 * (obs.t - 2.5))
        target = np.array([MUG[0] + self.offset[0], MUG[1] + self.offset[1], z])
        return TeleopCommand(target, abs(obs.t - self.grasp_t) < 1e-3)


def _practice(keys: _Keys) -> Trial:
    config = load_protocol(PAPER_PROTOCOL).config_for("training", "none")
    return Trial(config, keys, keep_records=False)


def _resisted(trial: Trial, seconds: float, *, held: list[float] | None = None) -> list[float]:
    """Trial times at which ``ResistedDescent`` (fed as the live run feeds it) said so; the
    times the trial held the hand above an object go to ``held``."""
    seen, out = ResistedDescent(), []
    while trial.t < seconds and not trial.done:
        rec = trial.tick()
        if held is not None and trial.held_above is not None:
            held.append(rec.t)
        touching = any(part in FINGERS for part, _ in trial.contacts.touching)
        if seen.update(
            rec.t,
            z=float(rec.ee[2]),
            target_z=float(trial.user_target[2]),
            touching=trial.task.reaching and touching,
        ):
            out.append(rec.t)
    return out


def test_a_gripper_over_the_mugs_rim_is_held_above_it_and_said_so() -> None:
    """2.2 cm beside the mug's axis across the slot a fingertip would land on the rim (the mug
    is 2.8 cm in radius, the open fingers 4 cm from the TCP): F held, the gripper is held
    just clear of the top (``app.teleop.guarded_descent``: ``held_above``, the page's
    notice) and never rests on it; until the guard, it hopped on the rim and the mug fell."""
    trial = _practice(_Keys((0.0, 0.022), floor=0.02))
    held = []
    assert _resisted(trial, 6.0, held=held) == []  # nothing rests on the rim
    assert held and held[0] < 4.5, held  # the descent is stopped at about 3 s
    assert trial.held_above == 0 and trial.accidents.count == 0
    assert not trial.contacts.touching


def test_a_finger_on_a_rim_is_seen_holding_the_gripper_up() -> None:
    """Fed as the live run feeds it: a finger touching (on and off, as it slips on a rim), the
    target 5 cm below, the gripper not coming down: held up after ``RESISTED_S``."""
    seen = ResistedDescent()
    said = [
        seen.update(t / 100, z=0.2, target_z=0.15, touching=(t // 20) % 2 == 0) for t in range(100)
    ]
    assert not any(said[:45]) and all(said[55:])
    seen = ResistedDescent()
    coming_down = [
        seen.update(t / 100, z=0.2 - 0.05 * t / 100, target_z=0.1, touching=True)
        for t in range(100)
    ]
    assert not any(coming_down)


def test_a_gripper_lowered_around_the_mug_is_not_held_up() -> None:
    trial = _practice(_Keys((0.0, 0.005), floor=MUG[2], grasp_t=4.5))
    assert _resisted(trial, 8.0) == []
    assert trial.outcome == "success"


def test_a_missed_grasp_keeps_the_gripper_closed_a_moment_then_opens_it() -> None:
    trial = _practice(_Keys((-0.15, 0.15), floor=0.15, grasp_t=1.0))  # far from the mug
    phases, opening = {}, {}
    while trial.t < 1.0 + CLOSE_S + MISSED_HOLD_S + REOPEN_S + 0.2:
        trial.tick()
        phases.setdefault(trial.task.phase, trial.t)
        opening[round(trial.t, 2)] = trial.sim.gripper_opening
    miss = phases["missed"]
    assert miss == pytest.approx(1.0 + CLOSE_S, abs=0.02)
    closed = [t for t, o in opening.items() if o < 0.005]
    assert max(closed) - min(closed) >= MISSED_HOLD_S
    assert phases["reopening"] == pytest.approx(miss + MISSED_HOLD_S, abs=0.03)
    assert trial.task.phase == "reach" and trial.sim.gripper_opening > 0.035


def test_f_held_to_the_table_around_the_mug_stops_the_palm_above_it_and_says_press_g() -> None:
    """F held until the target reaches the reach's floor, the mug between the fingers: the
    palm stops clear of the mug's top (it landed on it, and the hand bounced there by itself),
    the trial says so (``resting_on``: the page's "as low as it goes" notice), and G grasps."""
    trial = _practice(_Keys((0.0, 0.004), floor=0.02, grasp_t=5.5))
    resting, lowest = [], 1.0
    while trial.t < 5.4:
        trial.tick()
        lowest = min(lowest, float(trial.sim.ee[2]))
        if trial.resting_on is not None:
            resting.append(trial.t)
        assert not trial.contacts.touching, (trial.t, trial.contacts.touching)
    assert resting and resting[0] < 4.5 and trial.resting_on == 0
    assert lowest > MUG[2] - 0.01  # a few millimetres under the grasp point, not on the table
    while not trial.done and trial.t < 10.0:
        trial.tick()
    assert trial.outcome == "success" and trial.accidents.count == 0


@pytest.mark.parametrize(("dx", "centred"), [(0.003, True), (0.015, True), (0.027, False)])
def test_as_low_as_it_goes_says_whether_the_object_is_in_the_middle_of_the_fingers(
    dx: float, centred: bool
) -> None:
    """Off the mug's axis along the fingers by 2.7 cm, closing lets the mug slip out on the lift
    (``benchmarks/grasp_offsets.py``: it slips at 3 cm, holds to 2.5): the trial says the hand
    is not centred there (the page's ``NOT_CENTRED`` notice) rather than inviting G; 1.5 cm off
    it holds, and G is invited."""
    trial = _practice(_Keys((dx, 0.0), floor=0.02))
    while trial.t < 5.0:
        trial.tick()
    assert trial.resting_on == 0 and trial.resting_centred is centred


def test_f_held_to_the_floor_around_the_robots_object_is_as_low_as_it_goes() -> None:
    """Over the box with the robot taking the hand there (its policy sets the height, not the
    palm's stop), F held to the reach's floor: the hand is as low as it goes all the same (the
    page said "only inside the frame", which a tester read as the outline they were inside)."""
    config = load_protocol(PAPER_PROTOCOL).config_for("easy-right", "aggressive")
    probe = Trial(config, _Keys((0.0, 0.0), floor=1.0), keep_records=False)
    k = probe.scene.object_names.index("box")
    box = probe._grasp_points[k]
    keys = _Keys((float(box[0] - MUG[0]), float(box[1] - MUG[1])), floor=0.0)
    trial = Trial(config, keys, keep_records=False)
    resting = []
    while trial.t < 6.0 and not trial.done:
        trial.tick()
        if trial.resting_on is not None:
            resting.append((trial.resting_on, round(trial.t, 2)))
    assert resting and resting[-1][0] == k, resting[-3:]
    assert not any(obj == k for _, obj in trial.contacts.touching)


def test_a_hand_high_over_an_object_is_not_as_low_as_it_goes() -> None:
    """Over the mug at 15 cm, the input held there: nothing is said (the hand, 18 cm over the
    box at the reach's edge, once showed "as low as it goes" over the reach notice)."""
    trial = _practice(_Keys((0.0, 0.0), floor=0.15))
    while trial.t < 3.0:
        trial.tick()
        assert trial.resting_on is None, trial.t


@pytest.mark.parametrize("dx", [0.045, 0.055])
def test_f_held_beside_the_mug_stops_the_palm_above_it_and_says_not_in_the_middle(
    dx: float,
) -> None:
    """4.5-5.5 cm off the mug's axis along the slot the fingers pass beside the mug, but the
    palm (3.2 cm to each side of the TCP along the slot, 4.7 cm above the fingertips) does not:
    a tester's hand came down there with its palm on the mug's rim for 5 s. F held to the
    table: the palm stops clear of the top, nothing touches, and the trial says the hand is
    not centred (the page's "not in the middle ... W/S" notice)."""
    trial = _practice(_Keys((dx, 0.0), floor=0.02))
    while trial.t < 6.0:
        trial.tick()
        assert not trial.contacts.touching, (trial.t, trial.contacts.touching)
    assert trial.resting_on == 0 and trial.resting_centred is False
    assert trial.accidents.count == 0


@pytest.mark.parametrize("dx", [0.060, -0.0595])
def test_f_held_at_the_edge_of_the_palms_footprint_keeps_the_hand_still(dx: float) -> None:
    """6 cm off the mug's axis along the slot the palm's footprint ends: a tester's hand went
    up and down there by 3 cm twice a second for as long as F was held (the IK's 1-2 mm of
    sway took it in and out of the footprint, and each time in, the palm stop raised it); a
    hair nearer, on the other side, it hovered 2 cm above the table and the trial's "as low as
    it goes" switched every tick. F held to the table for 3 s: the hand stays within 5 mm, it
    touches nothing, and what the trial says of it does not change."""
    trial = _practice(_Keys((dx, 0.0), floor=0.02))
    while trial.t < 5.0:  # the target reaches the table at 3.8 s, the hand by 5 s
        trial.tick()
    zs, resting = [], set()
    while trial.t < 8.0:
        trial.tick()
        zs.append(float(trial.sim.ee[2]))
        resting.add(trial.resting_on)
        assert not trial.contacts.touching, (trial.t, trial.contacts.touching)
    assert max(zs) - min(zs) < 0.005, (min(zs), max(zs))
    assert len(resting) == 1, resting
    assert trial.accidents.count == 0


@pytest.mark.parametrize("dx", [0.062, 0.064, -0.062, -0.064])
def test_f_held_beside_the_bottle_stops_the_wrist_above_it(dx: float) -> None:
    """Beside the paper scene's 20-cm bottle the palm's footprint ends 6.2 cm off its axis along
    the slot, but the wrist's part of the hand, 10.4 cm above the TCP and 4.4 cm to each side
    along the slot, reaches over it: the open hand lowered 6.2-6.4 cm off, with no assistance,
    knocked the bottle over on one side and hovered against it on the other. F held to the
    table for 8 s: nothing of the hand touches the bottle, it stands, and the hand, stopped with
    the wrist clear of its top, stays within 5 mm."""
    config = load_protocol(PAPER_PROTOCOL).config_for("easy-right", "none")
    probe = Trial(config, _Keys((0.0, 0.0), floor=1.0), keep_records=False)
    k = probe.scene.object_names.index("bottle")
    bottle = probe._grasp_points[k]
    keys = _Keys((float(bottle[0] + dx - MUG[0]), float(bottle[1] - MUG[1])), floor=0.0)
    trial = Trial(config, keys, keep_records=False)
    zs = []
    while trial.t < 10.0 and not trial.done:
        trial.tick()
        assert not any(obj == k for _, obj in trial.contacts.touching), trial.t
        if trial.t > 7.0:
            zs.append(float(trial.sim.ee[2]))
    assert trial.accidents.count == 0
    assert max(zs) - min(zs) < 0.005, (min(zs), max(zs))

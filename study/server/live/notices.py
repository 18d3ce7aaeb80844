"""``HeldNotices``: the one notice the trial screen holds over the scene, and which it is.

The control thread stamps what it saw, in monotonic seconds: the input held past the reach
(``at_limit``), a missed grasp (``missed``; a new grasp request, ``asked``, takes its notice
down), the gripper held up by an object it rests on (``resting``, from :class:`ResistedDescent`),
the open gripper kept above an object it would come down on (``above``, the trial's
``held_above`` while the input asks it lower), the open gripper as low as it goes around an
object (``lowest``, the trial's ``resting_on``; ``off_centre`` when not centred on it along the
fingers), an object down and waiting to be put back
(``fallen``), a grasped object that slipped out (``slipped``; like a miss, until the next
grasp request; why, when the hand was down off the object's middle as G was pressed: then a
miss is said first too, and why) and, standing, still waits to be put back (``dropped``; said
so once it has been down ``PUT_BACK_S``). A grasp request (``asked``) takes down what was said
of the open hand (kept above, as low as it goes) and of the reach, which the live run stamps
only while the hand is the participant's (``reaching``): testers saw "not in the middle ...
press G" stay over the closing, lifting and reopening fingers, and the reach notice flash there
with F still held.
The render loop asks :meth:`HeldNotices.text` each period and shows the answer with
``ParticipantPage.hold_notice`` (one notice at a time; ``None`` takes it down). What the
participant's input does this moment comes first, after a fallen or dropped object (nothing
else matters until it stands at its spot again, and it waits for the gripper to leave the spot;
the slipped notice says so) and a slip, for ``MISSED_NOTICE_S`` or until the next grasp request
(the object is put back within a second and the open hand sinks back to where it was: under the
"not in the middle" notice a tester saw the slip's for 0.5-0.9 s, too short to read, and the
scene looked as before G): a resting finger (a
held F with a finger on a rim also drives the target below the reach's floor; the reach notice
would not say why the gripper stays up, a new-participant pass found), the gripper kept above
an object, the gripper as low as it goes around one (F held on, the target also reaches the
reach's floor, where the reach notice would only mislead), then the reach, then a miss.

A missed grasp's notice stays ``MISSED_NOTICE_S``: a three-second corner notice went unseen by
a tester whose eyes were on the gripper (and on a page drawing 10 frames a second, the closing
fingers showed in a frame or two), who then could not tell whether G had worked at all.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from app.teleop.guarded_descent import CENTRED_M
from app.trial import Trial
from app.trial.events import EventKind, TrialEvent
from study.server.live.texts import (
    AS_LOW_AS_IT_GOES,
    AT_REACH_LIMIT,
    FELL_OVER,
    HELD_ABOVE,
    MISSED_GRASP,
    MISSED_OFF_CENTRE,
    RESTING_ON_OBJECT,
    SLIPPED_OFF_CENTRE,
    SLIPPED_OUT,
    SLIPPED_WAITING,
    not_centred,
    toward_middle,
)

LIMIT_HOLD_S = 0.4
"""The reach notice stays this long after the input was last held past the reach."""
MISSED_NOTICE_S = 5.0
"""A missed grasp's notice stays this long (or until the next grasp request)."""
PUT_BACK_S = 1.0
"""A dropped object still waiting this long after its slip is said to wait for the gripper
(it is put back 0.3-0.7 s after a slip when nothing is in its way)."""
RESTING_HOLD_S = 1.5
"""The resting notice stays this long after the gripper was last seen held up: a finger on a
rim slips on and off it several times a second."""

NEVER = -1e18

_SLIPPED = (EventKind.DROPPED, EventKind.LIFT_FAILED)
"""A grasped object out of the gripper again (``app.trial.tasks.lift``)."""


@dataclass
class HeldNotices:
    """When (monotonic s) each situation was last seen; :meth:`text` says which notice shows."""

    at_limit: float = NEVER
    missed: float = NEVER
    asked: float = NEVER
    resting: float = NEVER
    above: float = NEVER
    lowest: float = NEVER
    off_centre: float = NEVER
    fallen: float = NEVER
    slipped: float = NEVER
    dropped: float = NEVER
    centred: float = NEVER
    """When the open hand last rested centred on an object (the trial's ``resting_centred``)."""
    off_by: float = 0.0
    """How far (m, world x) the resting hand was off the object's middle when ``off_centre``
    was last stamped."""
    asked_offset: float = 0.0
    """How far (m, world x) the open hand was off the middle of the object it was down around
    at the last grasp request, 0 when centred or around none (the trial's ``grasp_offset``)."""

    def ask(self, now: float, *, offset: float) -> None:
        """A grasp request at ``now``, the hand ``offset`` off the object's middle."""
        self.asked_offset = offset
        self.asked = now

    def note_tick(
        self, trial: Trial, events: Sequence[TrialEvent], now: float, *, past_reach: bool
    ) -> None:
        """Stamp at ``now`` what ``trial``'s last tick (its ``events``) shows; ``past_reach``:
        the participant's input pushed past the reach. What the open hand does is stamped only
        while it is the participant's (``reaching``): while the task closes, lifts or reopens
        the gripper the trial's notes of it are from the last reach tick."""
        if TrialEvent(EventKind.GRASP_MISSED) in events:
            self.missed = now
        if TrialEvent(EventKind.GRASP_REQUESTED) in events:
            self.ask(now, offset=trial.grasp_offset)
        if any(e.kind in _SLIPPED for e in events):
            self.slipped = now
        if trial.task.reaching:
            if past_reach:
                self.at_limit = now
            if trial.held_above is not None:
                self.above = now
            if trial.resting_on is not None:
                self.lowest = now
                if not trial.resting_centred:
                    self.off_centre, self.off_by = now, trial.resting_offset
                else:
                    self.centred = now
        accidents = trial.accidents
        if accidents.down and accidents.reset_objects:
            if accidents.fallen:
                self.fallen = now
            if len(accidents.fallen) < len(accidents.down):  # slipped out, standing
                self.dropped = now

    def _open_hand(self, now: float) -> str | None:
        """What is said of the open hand kept above or as low as it goes (a grasp request
        takes down what was said before it), or ``None``."""
        if now - self.above < LIMIT_HOLD_S and self.above > self.asked:
            return HELD_ABOVE
        if now - self.lowest < LIMIT_HOLD_S and self.lowest > self.asked:
            if self.off_centre >= self.lowest:
                return not_centred(self.off_by, centred_m=CENTRED_M)
            return AS_LOW_AS_IT_GOES
        return None

    def text(self, now: float, *, live: bool) -> str | None:
        """The notice to hold at ``now`` (``None``: none), only while the run is ``live``."""
        if not live:
            return None
        if now - self.fallen < LIMIT_HOLD_S:
            return FELL_OVER
        waiting = now - self.dropped < LIMIT_HOLD_S
        if waiting and self.dropped - self.slipped >= PUT_BACK_S:  # still down a second on
            return SLIPPED_WAITING
        way = toward_middle(self.asked_offset)
        missed = now - self.missed < MISSED_NOTICE_S and self.asked <= self.missed
        # once the hand named after an off-centre G has rested centred, its advice is done:
        # what the hand does now is said (overshot, "not in the middle" names the other key)
        if not (self.asked_offset and self.centred > self.asked and not waiting):
            if waiting or (now - self.slipped < MISSED_NOTICE_S and self.asked <= self.slipped):
                # said first: the hand sinks back at once, and under other notices it was unread
                return SLIPPED_OFF_CENTRE.format(way=way) if self.asked_offset else SLIPPED_OUT
            if missed and self.asked_offset:  # also said first: the hand opens where it was
                return MISSED_OFF_CENTRE.format(way=way)
        if now - self.resting < RESTING_HOLD_S:  # what really holds the gripper up
            return RESTING_ON_OBJECT
        if (held := self._open_hand(now)) is not None:
            return held
        if now - self.at_limit < LIMIT_HOLD_S and self.at_limit > self.asked:
            return AT_REACH_LIMIT
        return MISSED_GRASP if missed and not self.asked_offset else None

    def forget(self) -> None:
        """A new run: nothing seen yet."""
        self.at_limit = self.missed = self.asked = self.resting = self.above = self.lowest = NEVER
        self.fallen = self.slipped = self.dropped = self.off_centre = NEVER
        self.asked_offset = self.off_by = 0.0
        self.centred = NEVER


RESISTED_GAP_M = 0.03
"""The input's target lies this far below the gripper or more: it asks the gripper down (a held
key leads the gripper by 2 cm; a descent the arm follows stays within that)."""
RESISTED_DROP_M = 0.005
"""... and the gripper came down less than this over ``RESISTED_S``."""
RESISTED_S = 0.5


class ResistedDescent:
    """Whether the gripper is held up by an object: a finger touched one within the last
    ``RESISTED_S`` (on a rim it slips on and off), the participant's target lies
    ``RESISTED_GAP_M`` or more below the gripper, and the gripper came down less than
    ``RESISTED_DROP_M`` in the last ``RESISTED_S``: the arm cannot go lower there, whatever the
    keys say. Fed once per control tick (:meth:`update`)."""

    def __init__(self) -> None:
        self._since: tuple[float, float] | None = None  # (t, gripper z) when it began
        self._touched = NEVER

    def update(self, t: float, *, z: float, target_z: float, touching: bool) -> bool:
        """One tick at trial time ``t``: the gripper's height ``z``, the target's ``target_z``,
        whether a finger touches an object. True while the descent is resisted."""
        if touching:
            self._touched = t
        if t - self._touched > RESISTED_S or target_z > z - RESISTED_GAP_M:
            self._since = None
            return False
        if self._since is None or z < self._since[1] - RESISTED_DROP_M:
            self._since = (t, z)  # (still) coming down: measure from here
            return False
        return t - self._since[0] >= RESISTED_S


__all__ = [
    "LIMIT_HOLD_S",
    "MISSED_NOTICE_S",
    "PUT_BACK_S",
    "RESISTED_DROP_M",
    "RESISTED_GAP_M",
    "RESISTED_S",
    "RESTING_HOLD_S",
    "HeldNotices",
    "ResistedDescent",
]

"""The arm's touches on objects as events: which part, which object, how hard.

``ContactLog.update(touches, dt=..., grasping=...)`` takes the contact points of one control tick
(``Simulation.arm_contacts``: part, object, normal force) and returns the events of that tick
(``app.trial.events``):

- ``contact`` (part, object) when a part starts touching an object (one event per touch);
- ``contact_end`` (part, object, impulse) when it stops, with the touch's normal impulse in
  N s, ``J = sum over ticks of (sum of the pair's normal forces) * dt`` (forces sampled once per
  tick, after its last physics substep).

A touch is over once the pair has been apart for ``GAP_S``: a finger dragged along a bottle
makes and breaks contact every few milliseconds, and that is one touch, not twenty (the end is
logged at the tick the gap is complete).

A grasp is not a collision: while ``grasping`` (the gripper closing or lifting) the fingers'
touches on the object between them are tracked but produce no events. ``count`` and
``impulse_ns`` total the logged touches of the trial (the dependent measure beside time);
``close()`` ends the touches still going at the end of the trial.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from app.robot.simulation import ARM_PARTS
from app.trial.events import EventKind, TrialEvent

GAP_S = 0.1
"""Apart this long (s), a touch has ended; a shorter break continues it."""

FINGERS = frozenset(k for k, name in enumerate(ARM_PARTS) if name.endswith("finger"))


class ContactLog:
    """Touch onsets and ends of one trial, from per-tick contact points."""

    def __init__(self, object_names: Sequence[str], *, gap_s: float = GAP_S) -> None:
        self.object_names = tuple(object_names)
        self.gap_s = gap_s
        self.count = 0
        self.impulse_ns = 0.0
        self._touching: dict[tuple[int, int], float] = {}  # (part, object) -> impulse so far
        self._apart: dict[tuple[int, int], float] = {}  # (part, object) -> seconds apart
        self._silent: set[tuple[int, int]] = set()  # grasp touches: tracked, never logged

    @property
    def touching(self) -> frozenset[tuple[int, int]]:
        """The ``(part, object)`` pairs in touch now (a break shorter than ``gap_s`` included)."""
        return frozenset(self._touching)

    def update(
        self,
        touches: Sequence[tuple[int, int, float]],
        *,
        dt: float,
        grasping: bool,
        held: int | None = None,
    ) -> list[TrialEvent]:
        """Events of one tick from its contact points ``(part, object, normal force N)``.

        ``grasping``: fingers touching an object are part of the grasp (``held``, if known,
        narrows it to that object); their touches are not logged.
        """
        if not touches and not self._touching:
            return []  # no touch now and none going on (most ticks)
        force: dict[tuple[int, int], float] = {}
        for part, obj, f in touches:
            key = (part, obj)
            force[key] = force.get(key, 0.0) + f
        events: list[TrialEvent] = []
        for key in [k for k in self._touching if k not in force]:
            self._apart[key] = self._apart.get(key, 0.0) + dt
            if self._apart[key] >= self.gap_s - 1e-9:
                events.extend(self._end(key))
        for key, f in force.items():
            self._apart.pop(key, None)
            if key not in self._touching:
                part, obj = key
                if grasping and part in FINGERS and (held is None or held == obj):
                    self._silent.add(key)
                else:
                    self.count += 1
                    events.append(
                        TrialEvent(
                            EventKind.CONTACT, part=ARM_PARTS[part], obj=self.object_names[obj]
                        )
                    )
                self._touching[key] = 0.0
            self._touching[key] += f * dt
        return events

    def close(self) -> list[TrialEvent]:
        """End every touch still going (the trial is over)."""
        events: list[TrialEvent] = []
        for key in list(self._touching):
            events.extend(self._end(key))
        return events

    def _end(self, key: tuple[int, int]) -> list[TrialEvent]:
        impulse = self._touching.pop(key)
        self._apart.pop(key, None)
        if key in self._silent:
            self._silent.discard(key)
            return []
        self.impulse_ns += impulse
        part, obj = key
        touch = TrialEvent(
            EventKind.CONTACT_END,
            part=ARM_PARTS[part],
            obj=self.object_names[obj],
            impulse_ns=impulse,
        )
        return [touch]


def contact_totals(events: Iterable[TrialEvent]) -> tuple[int, float]:
    """``(touches, impulse N s)`` of a trial from its logged events (the measure ``ContactLog``
    keeps while it runs), for readers of the store or an export: ``contact`` onsets counted,
    ``contact_end`` impulses summed."""
    count, impulse = 0, 0.0
    for event in events:
        if event.kind is EventKind.CONTACT:
            count += 1
        elif event.kind is EventKind.CONTACT_END and event.impulse_ns is not None:
            impulse += event.impulse_ns
    return count, impulse

"""Objects knocked over or pushed off the table, and the experimenter who stands them up again.

``Accidents.check(t, held=...)`` runs every few control ticks and returns the events of that
check and, under ``on_knock = "end"``, the outcome the trial ends with:

- ``knocked_over:<obj>`` once an object not in the gripper tilts past ``TILT_RAD`` (about 40
  degrees: it is lying, no longer standing);
- ``pushed_off:<obj>`` once its centre falls ``OFF_TABLE_M`` below the table top (also after
  a knock).

Under ``on_knock = "reset"`` (the default: what an experimenter does) the run goes on and the
object is put back; so is a held object that slipped out of the gripper (``slipped``: where a
drop leaves it, turned or against another object, a top-down grasp may no longer be possible,
and the scene is no longer the one the condition defines). It is put back once it has settled
(slower than ``SETTLE_SPEED_M_S`` and ``SETTLE_SPIN_RAD_S`` for ``SETTLE_S``, or
``MAX_SETTLE_S`` after the accident; an object off the table after ``PICKUP_S``), nothing holds it, no arm part touches it and its start pose is free,
its free joint is set to the start pose at rest (``qpos = qpos_0``, ``qvel = 0``, forward) and
``object_reset:<obj>`` is logged. Whether the start pose is free is asked of MuJoCo's collision
detection at that pose: the object is placed there and, if it would overlap the hand, a finger
or another object by more than ``CLEAR_M``, put back where it lay and tried again at the next
check (the hand hovering over the spot waits). A reset object can be knocked over again, and
each knock counts.

Under ``on_knock = "end"`` the first accident ends the trial: outcome ``knocked_over`` or
``pushed_off`` (the scene is no longer the one the condition defines).

``knocks`` and ``pushes`` count the accidents per object, ``resets`` the objects put back;
``down`` names the objects waiting to be put back, ``fallen`` those of them knocked or pushed.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from app.robot.simulation import Simulation
from app.trial.config import ON_KNOCK
from app.trial.errors import TrialConfigError
from app.trial.events import EventKind, TrialEvent

TILT_RAD = 0.7
"""An object tilted beyond this (about 40 degrees) is knocked over: it will not stand again."""
SETTLE_S = 0.3
"""A knocked object this long below both settle speeds has settled and can be stood up."""
SETTLE_SPEED_M_S = 0.02
SETTLE_SPIN_RAD_S = 0.5
MAX_SETTLE_S = 2.0
"""A knocked object still rocking this long after the knock is stood up anyway (when free)."""
PICKUP_S = 0.5
"""An object off the table is put back this long after it fell (the experimenter picks it up)."""
CLEAR_M = 0.001
"""The start pose counts as occupied when the object would sink this far into anything there."""


@dataclass
class _Down:
    """An object waiting to be put back: why, since when, and since when it has been still."""

    reason: EventKind
    since: float
    still_since: float | None = None


class Accidents:
    """Knocks and falls of one trial's objects, and their reset (see the module docstring)."""

    def __init__(self, sim: Simulation, names: Sequence[str], *, on_knock: str = "reset") -> None:
        if on_knock not in ON_KNOCK:
            raise TrialConfigError(f"on_knock: one of {ON_KNOCK}, got {on_knock!r}")
        self.sim = sim
        self.names = tuple(names)
        self.reset_objects = on_knock == "reset"
        self.knocks: Counter[str] = Counter()
        self.pushes: Counter[str] = Counter()
        self.resets: Counter[str] = Counter()
        self._down: dict[int, _Down] = {}
        self.count = 0
        """Accidents so far (knocks and falls off the table, every object)."""
        self.down: tuple[int, ...] = ()
        """The objects waiting to be put back (knocked over, off the table, or slipped out of
        the gripper)."""
        self.fallen: tuple[int, ...] = ()
        """Those of ``down`` knocked over or off the table (not a drop)."""
        model, data = sim.model, sim.data
        bodies = sim.scene.object_body_ids
        self._qadr = [int(a) for a in sim.scene.object_qpos_addr]
        self._dofadr = [int(model.body_dofadr[b]) for b in bodies]
        self._start = [data.qpos[a : a + 7].copy() for a in self._qadr]
        self._geoms = [frozenset(np.flatnonzero(model.geom_bodyid == b).tolist()) for b in bodies]
        table = model.geom("table").id
        self._ignore = frozenset({table, model.geom("floor").id})

    def lying(self, k: int) -> bool:
        """Object ``k`` waits to be put back (knocked over, pushed off or dropped)."""
        return k in self._down

    def slipped(self, k: int, t: float) -> None:
        """Object ``k`` slipped out of the gripper at ``t`` (dropped, or it would not come up):
        under ``on_knock = "reset"`` it is put back at its start pose like a knocked object,
        once it has settled and its spot is free (the drop itself is the task's event); if it
        falls over meanwhile, that is a knock. Standing, it is still an object the open hand is
        guarded around (it is in ``down``, not in ``fallen``)."""
        if self.reset_objects and k not in self._down:
            self._down[k] = _Down(EventKind.DROPPED, t)
            self._note_down()

    def check(self, t: float, *, held: int | None) -> tuple[list[TrialEvent], str | None]:
        """This check's events and, under ``on_knock = "end"``, the outcome to end with."""
        sim = self.sim
        events: list[TrialEvent] = []
        outcome: str | None = None
        off = set(sim.objects_off_table())
        tilts = sim.object_tilts().tolist()  # Python floats: compared one by one below
        for k, name in enumerate(self.names):
            down = self._down.get(k)
            if k in off and (down is None or down.reason is not EventKind.PUSHED_OFF):
                self.pushes[name] += 1
                self._down[k] = _Down(EventKind.PUSHED_OFF, t)
                events.append(TrialEvent(EventKind.PUSHED_OFF, obj=name))
                outcome = outcome or "pushed_off"
            elif (
                (down is None or down.reason is EventKind.DROPPED)
                and k != held
                and (tilts[k] > TILT_RAD)
            ):  # a dropped object that then falls over is knocked over too
                self.knocks[name] += 1
                self._down[k] = _Down(EventKind.KNOCKED_OVER, t)
                events.append(TrialEvent(EventKind.KNOCKED_OVER, obj=name))
                outcome = outcome or "knocked_over"
        if events:
            self.count = sum(self.knocks.values()) + sum(self.pushes.values())
            self._note_down()
        if not self.reset_objects:
            return events, outcome
        if self._down:
            touched = {obj for _, obj, _ in sim.arm_contacts()}
            for k in sorted(self._down):
                if k != held and k not in touched and self._settled(k, t) and self._place(k):
                    del self._down[k]
                    self._note_down()
                    self.resets[self.names[k]] += 1
                    events.append(TrialEvent(EventKind.OBJECT_RESET, obj=self.names[k]))
        return events, None

    # ---- internals -----------------------------------------------------------------------------
    def _note_down(self) -> None:
        self.down = tuple(sorted(self._down))
        self.fallen = tuple(k for k in self.down if self._down[k].reason is not EventKind.DROPPED)

    def _settled(self, k: int, t: float) -> bool:
        down = self._down[k]
        if down.reason is EventKind.PUSHED_OFF:
            return t - down.since >= PICKUP_S
        v = self.sim.data.qvel[self._dofadr[k] : self._dofadr[k] + 6]
        still = (
            float(np.linalg.norm(v[:3])) < SETTLE_SPEED_M_S
            and float(np.linalg.norm(v[3:])) < SETTLE_SPIN_RAD_S
        )
        if not still:
            down.still_since = None
        elif down.still_since is None:
            down.still_since = t
        settled = down.still_since is not None and t - down.still_since >= SETTLE_S - 1e-9
        return settled or t - down.since >= MAX_SETTLE_S

    def _place(self, k: int) -> bool:
        """Object ``k`` at its start pose, at rest; ``False`` (nothing changed) if it would
        overlap anything there but the table."""
        model, data = self.sim.model, self.sim.data
        q, v = self._qadr[k], self._dofadr[k]
        lying_q = data.qpos[q : q + 7].copy()
        lying_v = data.qvel[v : v + 6].copy()
        data.qpos[q : q + 7] = self._start[k]
        data.qvel[v : v + 6] = 0.0
        mujoco.mj_forward(model, data)  # poses and contacts at the start pose
        if self._occupied(k):
            data.qpos[q : q + 7] = lying_q
            data.qvel[v : v + 6] = lying_v
            mujoco.mj_forward(model, data)
            return False
        return True

    def _occupied(self, k: int) -> bool:
        data = self.sim.data
        ours = self._geoms[k]
        for i in range(data.ncon):
            contact = data.contact[i]
            g1, g2 = int(contact.geom[0]), int(contact.geom[1])
            other = g2 if g1 in ours else (g1 if g2 in ours else None)
            if other is not None and other not in self._ignore and contact.dist < -CLEAR_M:
                return True
        return False


ACCIDENT_MEASURES: dict[str, str] = {
    "knocks": "objects knocked over (any object; a reset object knocked again counts again)",
    "target_knocks": "of those, the target object",
    "pushes_off": "objects pushed off the table",
    "drops": "held objects that slipped out of the gripper (or would not come up)",
    "object_resets": (
        "objects put back at their start pose, knocked, off the table or dropped (on_knock = reset)"
    ),
}
"""The per-trial accident counts a reader of the logged events gets (``accident_totals``)."""


def accident_totals(events: Iterable[TrialEvent], *, target: str) -> dict[str, int]:
    """The trial's accident counts (``ACCIDENT_MEASURES``) from its logged events, ``target``
    naming the object the participant was asked for; what ``Accidents`` counts while it runs,
    for readers of the store or an export (a store from before resets counts the knock that
    ended a run the same way)."""
    totals = dict.fromkeys(ACCIDENT_MEASURES, 0)
    for event in events:
        kind = event.kind
        if kind is EventKind.KNOCKED_OVER:
            totals["knocks"] += 1
            totals["target_knocks"] += event.obj == target
        elif kind is EventKind.PUSHED_OFF:
            totals["pushes_off"] += 1
        elif kind is EventKind.DROPPED or kind is EventKind.LIFT_FAILED:
            totals["drops"] += 1
        elif kind is EventKind.OBJECT_RESET:
            totals["object_resets"] += 1
    return totals

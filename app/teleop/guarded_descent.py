"""The open hand comes down over an object only where the object fits between its fingers.

A participant lowering the open hand a couple of centimetres off an object's axis, across the
fingers' slot, put a fingertip on its rim: the contact pushed the hand, the lift-out rule
(``app.teleop.lift_out``) switched on and off with it, the hand hopped on the rim several times
a second and the object went over (a new-participant pass; ``benchmarks/rim_descent.py``: the
practice mug knocked or pushed at 4 of 7 offsets from 0 to 4.5 cm; 13 practice mugs knocked by
40 simulated participants). A person steering a real gripper stops above the object and
centres it first; so does ``U``.

For object ``k`` with its axis at ``o_k``, footprint radius ``r_k``, top at ``h_k`` and
half-width across the slot ``a_k`` (the slot lies along world y), the open slot's half-width
``s``, the fingertips ``b`` below the TCP ``x`` and a ``clearance`` ``c``, with
``z_k = h_k + b + c``: a point ``p`` (the hand, the target) *clears* ``k`` with margin ``g``
when the object fits between the fingers there (``|p_y - o_y| <= s - a_k - g``) or lies beside
them (``|p_x - o_x| >= r_k + PAD_M + g``). The guard *takes* ``k`` when the hand is over it
(``|x_xy - o_k,xy| < r_k + s + c``), its fingertips no lower than ``SINK_M`` below the top
(``x_z - b >= h_k - SINK_M``: above it, or on its rim), the user's target ``t`` lower than
``z_k``, and the hand and the target do not both clear ``k`` (``g = 0``). While it holds ``k``,
``U`` steers to

    (t_x, t_y, z_k + HOVER_M)

holding the hand just clear of the top while it follows the target sideways. The hold is a
state, not a test made afresh each tick: it lets go once the hand and the target have both
cleared ``k`` for ``SETTLE_S`` with the hand within ``MARGIN_M`` of where it was when they
began to (then it comes down around it; a drag sweeping across is not let down midway), once
the hand has left ``k``'s footprint by ``MARGIN_M``, or once the target rises to ``z_k``.
Over an object it let go of, it takes the hand again only if a point no longer clears ``k``
with ``g = -MARGIN_M`` (clearly off). So a noisy target near the edge of clearing, or a
finger brushing the rim, no longer switches it (and the lift-out rule with it) on and off
several times a second.
A hand already around the object (fingertips lower) is left to ``lift_out``.

Around the object, the open hand comes down only until its palm, ``p`` above the TCP, is
``PALM_CLEAR_M`` above the top: while the hand is over ``k`` with the object between its
fingers (the hand clears ``k``, not beside it), ``U`` steers to ``(t_x, t_y, max(t_z, r_k))``
with ``r_k = h_k - p + PALM_CLEAR_M`` (``rest``; a few millimetres under the grasp point, which
lies at most 3 cm under the top). A participant holding F to the table's reach put the palm
on the mug's top, the hand bounced on it by itself, and the mug went over (a new-participant
pass: the palm on the top after every one of 7 descents). The same stop holds while the palm's
footprint, ``palm_half`` ``(h_x, h_y)`` to each side of the TCP, overlaps ``k``'s
(``|x_x - o_x| < r_k + h_x`` and ``|x_y - o_y| < r_k + h_y``: ``under_palm``) with the fingers
beside it: the palm is wider than the pads, and a tester's hand lowered 4.5-5 cm off the mug's
axis along the slot came down with its palm on the rim for 5 s. Once the stop has let go of a
hand that left the footprint (``palm_left``), it takes it again only ``MARGIN_M`` inside
(``|x_x - o_x| < r_k + h_x - MARGIN_M`` and the same across), until the hand is ``MARGIN_M``
outside: at the footprint's edge, 6 cm off the mug's axis along the slot, the IK's 1-2 mm of
sway took the hand in and out of it and the stop raised it each time in (a tester's hand
bobbed 3 cm twice a second for as long as F was held, h9). It does so only over an object
whose top is under ``low``, where the hand beside it is its palm and fingers alone: the arm
above the palm (the wrist's parts, wider along the slot) stays over such an object however
low the hand goes; beside a taller one (the 20-cm bottle) the stop keeps taking the hand at
the footprint itself. The hand's ``parts`` above the palm stop it too: with part ``j``'s
bottom ``l_j`` above the TCP and its footprint ``e_j`` to each side, over every ``k`` with
``|x_x - o_x| < r_k + e_jx`` and ``|x_y - o_y| < r_k + e_jy`` (``r_k`` less ``MARGIN_M`` for
``palm_left``) the stop rises to ``h_k - l_j + PALM_CLEAR_M`` where that is higher. With the
palm's box alone, the wrist's part (10.4 cm above the TCP, 4.4 cm to each side along the slot)
came down on the bottle with the palm's footprint clear: lowered 6.2-6.4 cm off its axis along
the slot, the open hand knocked it over on one side and hovered against it at 16 cm on the
other.
The trial leaves out the object the robot is taking the hand to (``alpha > 0``), as
``lift_out`` does: its policy centres the hand there, and a user's target held off it would
only push against the robot lowering the hand.
"""

from __future__ import annotations

import math
from collections.abc import Container, Sequence

from app.teleop.lift_out import CLEARANCE_M

PAD_M = 0.012
"""The fingers' pads' half-width (along world x): an object farther than its radius plus this
from the hand's x lies beside the fingers."""
SINK_M = 0.005
"""Fingertips this far below the object's top or more are around it (or beside it), not on it."""
HOVER_M = 0.005
"""How far above ``z_k`` the hand is held: the tracking lag under a target pressed lower stays
above ``z_k``, where the lift-out rule has nothing to lift."""
SETTLE_S = 0.15
"""How long the hand and the target must both clear the held object, the hand settled, before
the hold lets go."""
MARGIN_M = 0.003
"""The hold's hysteresis: the footprint it lets go beyond, and how clearly off a point must be
to take the hand again over an object it let go of (the simulated hand's noise is 2 mm); and
the palm stop's: how far inside the footprint it takes again a hand it let go of there."""

PALM_CLEAR_M = 0.005
"""How far above the object's top the palm stays when the open hand is lowered around it."""
CENTRED_M = 0.02
"""The hand this near the object's axis along the slot (world x) is centred for a grasp: the
fingers' capsule pads lift and carry the practice mug closed on up to 2.5 cm off its axis, and
let it slip out at 3 cm (``benchmarks/grasp_offsets.py``); 2 cm leaves a participant's drift."""

Footprint = tuple[float, float, float, float, float]
"""An object as ``(x, y, footprint radius, top height, half-width across the slot)`` (m)."""
Part = tuple[float, float, float]
"""A part of the hand above the palm as ``(bottom above the TCP, half-extent along world x,
half-extent along world y)`` (m): the box it reaches over, centred on the TCP."""


def _clears(px: float, py: float, obj: Footprint, *, slot: float, margin: float) -> bool:
    """Whether the point ``p`` clears ``obj`` with ``margin`` ``g`` (module docstring)."""
    ox, oy, radius, _, half_width = obj
    return abs(py - oy) <= slot - half_width - margin or abs(px - ox) >= radius + PAD_M + margin


def _both_clear(
    x: Sequence[float], target: Sequence[float], obj: Footprint, *, slot: float, margin: float
) -> bool:
    """Whether the hand ``x`` and the target both clear ``obj`` with ``margin``."""
    return _clears(x[0], x[1], obj, slot=slot, margin=margin) and _clears(
        target[0], target[1], obj, slot=slot, margin=margin
    )


class DescentGuard:
    """Holds the open hand above an object it would come down on and stops it, lowered around
    one, with its palm just over the top (module docstring); one per trial, for a hand whose
    fingertips are ``reach_below`` under the TCP, whose palm is ``palm_above`` over it, and
    whose open slot's half-width is ``slot`` and whose palm reaches ``palm_half`` to each side
    of the TCP along world x and y, with its ``parts`` above the palm; objects whose top is
    under ``low`` meet only the palm and fingers of the hand lowered beside them as far as it
    goes (the palm stop's hysteresis is theirs). ``held``: the object held above, or
    ``None``."""

    def __init__(
        self,
        *,
        reach_below: float,
        slot: float,
        palm_above: float,
        palm_half: tuple[float, float] = (0.0, 0.0),
        parts: Sequence[Part] = (),
        low: float = -math.inf,
        clearance: float = CLEARANCE_M,
    ) -> None:
        self.reach_below = reach_below
        self.palm_above = palm_above
        self.palm_half = palm_half
        self.parts = tuple(parts)
        self._parts_lo = min((lo for lo, _, _ in self.parts), default=math.inf)
        self.low = low
        self.slot = slot
        self.clearance = clearance
        self.held: int | None = None
        self.palm_on: int | None = None
        """The object the palm stop held the hand above at the last ``rest``, or ``None``."""
        self.palm_left: int | None = None
        """The object whose footprint the hand left while the stop held it there, while the
        hand is still within ``MARGIN_M`` of it, or ``None``."""
        self._cleared: int | None = None  # the object last let go of, the hand still over it
        self._clear_since: tuple[float, float, float] | None = None  # (t, x, y) it began

    def steer(
        self,
        x: Sequence[float],
        target: Sequence[float],
        objects: Sequence[Footprint],
        *,
        now: float,
        skip: Container[int] = (),
    ) -> tuple[float, float, float] | None:
        """Where ``U`` steers instead of ``target`` at time ``now`` (s) while the guard holds an
        object (``None``: it holds none). A hold it lets go of this call returns ``None``
        without looking for a new one: the caller asks the lift-out rule first, then calls
        again."""
        xx, xy, xz = x
        tx, ty, tz = target
        if self.held is not None:
            return self._keep(self.held, x, target, objects[self.held], now, skip)
        reach_below, slot, clearance = self.reach_below, self.slot, self.clearance
        cleared = self._cleared
        for k, obj in enumerate(objects):
            ox, oy, radius, top, _ = obj
            near = radius + slot + clearance
            over = math.hypot(xx - ox, xy - oy) < near
            if k == cleared and not over:
                self._cleared = None  # the hand has left the object it came down on
            z_k = top + reach_below + clearance
            if not over or tz >= z_k or xz - reach_below < top - SINK_M or k in skip:
                continue
            loose = MARGIN_M if k == cleared else 0.0
            if _both_clear(x, target, obj, slot=slot, margin=-loose):
                continue
            self.held, self._cleared, self._clear_since = k, None, None
            return (tx, ty, z_k + HOVER_M)
        return None

    def _keep(
        self,
        k: int,
        x: Sequence[float],
        target: Sequence[float],
        obj: Footprint,
        now: float,
        skip: Container[int],
    ) -> tuple[float, float, float] | None:
        """The held object ``k``'s hold this tick, or ``None`` once it lets go."""
        xx, xy, _ = x
        tx, ty, tz = target
        reach_below, slot, clearance = self.reach_below, self.slot, self.clearance
        if k not in skip:
            ox, oy, radius, top, _ = obj
            z_k = top + reach_below + clearance
            if math.hypot(xx - ox, xy - oy) < radius + slot + clearance + MARGIN_M and tz < z_k:
                if not _both_clear(x, target, obj, slot=slot, margin=0.0):
                    self._clear_since = None
                    return (tx, ty, z_k + HOVER_M)
                since = self._clear_since
                if since is None or math.hypot(xx - since[1], xy - since[2]) > MARGIN_M:
                    since = self._clear_since = (now, xx, xy)  # a hand sweeping across restarts
                if now - since[0] < SETTLE_S:
                    return (tx, ty, z_k + HOVER_M)
                self._cleared = k  # centred: the hand comes down around it
        self.held = self._clear_since = None
        return None

    def around(
        self, x: Sequence[float], objects: Sequence[Footprint], *, skip: Container[int] = ()
    ) -> int | None:
        """The object the open hand at ``x`` is over with the object between its fingers (not
        on its rim, not beside it), or ``None``."""
        xx, xy, _ = x
        slot, clearance = self.slot, self.clearance
        for k, (ox, oy, radius, _, half_width) in enumerate(objects):
            if k in skip or math.hypot(xx - ox, xy - oy) >= radius + slot + clearance:
                continue
            if abs(xy - oy) <= slot - half_width and abs(xx - ox) < radius + PAD_M:
                return k
        return None

    def under_palm(
        self,
        x: Sequence[float],
        objects: Sequence[Footprint],
        *,
        skip: Container[int] = (),
        left: int | None = None,
    ) -> int | None:
        """The object whose footprint the palm of the hand at ``x`` overlaps (the object
        between the fingers first, ``around``), or ``None``; ``left``'s footprint counts only
        ``MARGIN_M`` inside (``palm_left``)."""
        k = self.around(x, objects, skip=skip)
        if k is not None:
            return k
        xx, xy, _ = x
        hx, hy = self.palm_half
        for k, (ox, oy, radius, _, _) in enumerate(objects):
            r = radius - MARGIN_M if k == left else radius
            if k not in skip and abs(xx - ox) < r + hx and abs(xy - oy) < r + hy:
                return k
        return None

    def rest(
        self,
        x: Sequence[float],
        target: Sequence[float],
        objects: Sequence[Footprint],
        *,
        skip: Container[int] = (),
    ) -> tuple[tuple[float, float, float], int] | None:
        """``U``'s target no lower than where the palm clears the top of the object the open
        hand is lowered around or beside, under its palm, and every part above it clears the
        top of each object under it (module docstring), and the object that stops it highest;
        ``None`` when the target is not below that height (or no object is there).
        Keeps ``palm_on`` and ``palm_left`` (the stop's hysteresis)."""
        held, left = self.palm_on, self.palm_left
        if left is not None and not self._near(x, objects[left]):
            left = None  # the hand is clear of the footprint it left
        k = self.under_palm(x, objects, skip=skip, left=left)
        tx, ty, tz = target
        rest_z = -math.inf if k is None else objects[k][3] - self.palm_above + PALM_CLEAR_M
        if self.parts:  # the parts above the palm, over objects taller than the palm's stop
            xx, xy, _ = x
            above = max(tz, rest_z)
            for j, (ox, oy, radius, top, _) in enumerate(objects):
                if top - self._parts_lo + PALM_CLEAR_M <= above or j in skip:
                    continue  # no part comes down to this top, or it does not stop it higher
                r = radius - MARGIN_M if j == left else radius
                for lo, hx, hy in self.parts:
                    z = top - lo + PALM_CLEAR_M
                    if z > above and abs(xx - ox) < r + hx and abs(xy - oy) < r + hy:
                        above = rest_z = z
                        k = j
        if k is None:
            self.palm_on = None
            if held is not None and objects[held][3] < self.low and self._near(x, objects[held]):
                left = held  # it left the footprint the stop held it over: let go
            self.palm_left = left
            return None
        if tz >= rest_z:
            self.palm_on, self.palm_left = None, None if k == left else left
            return None
        self.palm_on, self.palm_left = k, None if k == left else left
        return (tx, ty, rest_z), k

    def _near(self, x: Sequence[float], obj: Footprint) -> bool:
        """Whether the palm of the hand at ``x`` is within ``MARGIN_M`` of ``obj``'s
        footprint."""
        ox, oy, radius, _, _ = obj
        hx, hy = self.palm_half
        r = radius + MARGIN_M
        return abs(x[0] - ox) < r + hx and abs(x[1] - oy) < r + hy

    def state(self) -> tuple[float, ...]:
        """What the guard keeps between calls as numbers, for a compiled caller
        (``app.teleop.steer_core.STATE`` up to ``palm_left``): ``held``, the object last let go
        of, when (``t``, ``x``, ``y``) the hand and target began to clear the held one, ``palm_on``
        and ``palm_left``; ``-1`` for ``None`` (``NaN`` for no start)."""
        since = self._clear_since
        return (
            *(-1.0 if k is None else float(k) for k in (self.held, self._cleared)),
            *((math.nan,) * 3 if since is None else since),
            *(-1.0 if k is None else float(k) for k in (self.palm_on, self.palm_left)),
        )

    def set_state(self, values: Sequence[float]) -> None:
        """Take the state a compiled caller worked out (:meth:`state`'s numbers)."""
        held, cleared, t, x, y, palm_on, palm_left = values[:7]
        self.held = None if held < 0 else int(held)
        self._cleared = None if cleared < 0 else int(cleared)
        self._clear_since = None if math.isnan(t) else (t, x, y)
        self.palm_on = None if palm_on < 0 else int(palm_on)
        self.palm_left = None if palm_left < 0 else int(palm_left)

    def release(self) -> None:
        """Hold nothing (the gripper closed)."""
        self.held = self._cleared = self._clear_since = self.palm_on = self.palm_left = None


__all__ = [
    "CENTRED_M",
    "HOVER_M",
    "MARGIN_M",
    "PAD_M",
    "PALM_CLEAR_M",
    "SETTLE_S",
    "SINK_M",
    "DescentGuard",
    "Footprint",
    "Part",
]

"""The open hand comes down over an object only where the object fits between its fingers.

A participant lowering the open hand a couple of centimetres off an object's axis, across the
fingers' slot, put a fingertip on its rim: the contact pushed the hand, the lift-out rule
(``app.teleop.lift_out``) switched on and off with it, the hand hopped on the rim several times
a second and the object went over (a new-participant pass; ``benchmarks/rim_descent.py``: the
practice mug knocked or pushed at every offset from 2.5 to 4.5 cm). A person steering a real
gripper stops above the object and centres it first; so does ``U``.

For object ``k`` with its axis at ``o_k``, footprint radius ``r_k``, top at ``h_k`` and
half-width across the slot ``a_k`` (the slot lies along world y), the open slot's half-width
``s``, the fingertips ``b`` below the TCP ``x`` and a ``clearance`` ``c``: while the hand is over
``k`` (``|x_xy - o_k,xy| < r_k + s + c``), its fingertips no lower than ``SINK_M`` below the top
(``x_z - b >= h_k - SINK_M``: above it, or resting on its rim) and the user's target ``t`` below
``z_k = h_k + b + c``, a point ``p`` (the hand, the target) *clears* ``k`` when the object fits
between the fingers there (``|p_y - o_y| <= s - a_k - FIT_MARGIN_M``) or lies beside them
(``|p_x - o_x| >= r_k + PAD_M``). Unless both the hand and the target clear it, ``U`` steers to

    (t_x, t_y, z_k)

holding the hand just clear of the top while it follows the target sideways; it comes down
once the target and the hand clear the object, or the hand has left it. A hand already around
the object (fingertips lower) is left to ``lift_out``. The trial leaves out the object the
robot is taking the hand to (``alpha > 0``), as ``lift_out`` does: its policy centres the hand
there, and a user's target held off it would only push against the robot lowering the hand.
"""

from __future__ import annotations

import math
from collections.abc import Container, Iterable
from typing import NamedTuple

from app.teleop.lift_out import CLEARANCE_M

FIT_MARGIN_M = 0.0
"""How much room the fingers must leave on each side of the object to come down around it."""
PAD_M = 0.012
"""The fingers' pads' half-width (along world x): an object farther than its radius plus this
from the hand's x lies beside the fingers."""
SINK_M = 0.005
"""Fingertips this far below the object's top or more are around it (or beside it), not on it."""

Footprint = tuple[float, float, float, float, float]
"""An object as ``(x, y, footprint radius, top height, half-width across the slot)`` (m)."""


class Hold(NamedTuple):
    """``U``'s target held above object ``obj`` (its index)."""

    target: tuple[float, float, float]
    obj: int


def guard_descent(
    x: Iterable[float],
    target: Iterable[float],
    objects: Iterable[Footprint],
    *,
    reach_below: float,
    slot: float,
    clearance: float = CLEARANCE_M,
    skip: Container[int] = (),
) -> Hold | None:
    """Where ``U`` steers instead of ``target`` (module docstring), or ``None`` when no object
    is in the way of the descent; the objects whose indices are in ``skip`` are not considered."""
    xx, xy, xz = x
    tx, ty, tz = target
    for k, (ox, oy, radius, top, half_width) in enumerate(objects):
        if k in skip or math.hypot(xx - ox, xy - oy) >= radius + slot + clearance:
            continue
        floor = top + reach_below + clearance
        if tz >= floor or xz - reach_below < top - SINK_M:
            continue
        fit = slot - half_width - FIT_MARGIN_M
        beside = radius + PAD_M
        if all(abs(py - oy) <= fit or abs(px - ox) >= beside for px, py in ((xx, xy), (tx, ty))):
            continue
        return Hold((tx, ty, floor), k)
    return None


__all__ = ["FIT_MARGIN_M", "PAD_M", "SINK_M", "Footprint", "Hold", "guard_descent"]

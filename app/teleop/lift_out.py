"""The user's command takes the open hand out of an object it is around before going elsewhere.

An aggressive robot that is wrong takes the hand down around its own goal; when its confidence
drops, ``alpha`` falls to 0 in one tick and ``U`` -- a straight line from the TCP to the
user's target -- swept a finger through that object (8 simulated participants of the paper's
protocol: 14 knocks in 16 aggressive-and-wrong runs, none in any other cell); a participant
holding a key or dragging the handle away from an object the hand was around knocked it over
just the same (6 of 6 tries in Chromium). A teleoperation stack a person can trust does what the
person would: out first, then across.

For object ``k`` with its axis at ``o_k``, footprint radius ``r_k`` and top at height ``h_k``,
the hand with its fingertips ``b`` below the TCP ``x``, the open slot's half-width ``s`` and a
``clearance`` ``c``: the hand is over ``k`` when ``d_x = |x_xy - o_k,xy| < n_k = r_k + s + c``,
and the user's target ``t`` leaves ``k`` when ``d_t = |t_xy - o_k,xy| >= n_k`` or
``d_t > max(d_x, w) + e`` (it lies farther out than the hand, and more than ``w`` off the axis:
a key held or a handle dragged away leads the hand by two centimetres only; a target nearer
the axis centres the hand on the object). Then, with ``z_k = h_k + b + c``, ``U`` steers to

    (x_x, x_y, z_k + m)                  if x_z < z_k   (straight up)
    (t_x, t_y, max(t_z, z_k))            otherwise      (across, no lower than z_k while over k)

so the hand never moves sideways while its fingers could touch ``k``: it rises until they clear
the top by ``c`` (aiming ``m`` higher, since ``U`` slows as it nears its target and would creep
the last millimetres), and descends toward a low target only once it has left ``k``'s
footprint. A target that does not leave ``k`` (a grasp of it, centring on it) is followed as
given. The trial leaves out the object the robot is taking the hand to (``alpha > 0``): its
policy keeps the hand clear there; a user aiming beside that object would only push straight up
against the robot lowering the hand (a stalemate, Theorem 1's ``p = -u``: 2 timeouts in 304 runs
of a simulated pilot), and in a Hard task the user's target, held at the reach's edge, always
lies off the object the robot carries the hand to (the gripper stopped 3 cm short of the grasp).
So a user steering away from the object a timid robot still leans toward is not lifted.
"""

from __future__ import annotations

import math
from collections.abc import Container, Iterable

CLEARANCE_M = 0.01
"""``c``: how far the fingertips clear the object's top before the hand moves across."""
MARGIN_M = 0.02
"""``m``: how far above the height that clears the top the lift aims."""
LEAVING_M = 0.005
"""``e``: how much farther from the object's axis than the hand a target must lie to leave it."""
CENTRE_M = 0.01
"""``w``: a target this near the object's axis centres the hand on it, never leaves it."""

Cylinder = tuple[float, float, float, float]
"""An object as ``(x, y, radius, top height)`` in metres (world frame)."""


def lift_out(
    x: Iterable[float],
    target: Iterable[float],
    objects: Iterable[Cylinder],
    *,
    reach_below: float,
    slot: float,
    clearance: float = CLEARANCE_M,
    skip: Container[int] = (),
) -> tuple[float, float, float] | None:
    """The target ``U`` steers to instead of ``target`` (module docstring), or ``None`` when
    the hand is over no object the target leaves; the objects whose indices are in ``skip``
    are not considered."""
    xx, xy, xz = x
    tx, ty, tz = target
    for k, (ox, oy, radius, top) in enumerate(objects):
        if k in skip:
            continue
        near = radius + slot + clearance
        d_x = math.hypot(xx - ox, xy - oy)
        if d_x >= near:
            continue
        d_t = math.hypot(tx - ox, ty - oy)
        if d_t < near and d_t <= max(d_x, CENTRE_M) + LEAVING_M:
            continue
        floor = top + reach_below + clearance
        if xz < floor:
            return (xx, xy, floor + MARGIN_M)
        return (tx, ty, max(tz, floor))
    return None


__all__ = [
    "CENTRE_M",
    "CLEARANCE_M",
    "LEAVING_M",
    "MARGIN_M",
    "Cylinder",
    "lift_out",
]

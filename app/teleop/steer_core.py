"""The open hand's steering around objects, compiled: ``Steering.steer`` in one call.

Each tick the trial steers ``U``'s target around the objects (``app.trial.steering``,
``Steering.reference``): a hold above an object the guard keeps
(``DescentGuard.steer``), else out of an object the hand is around (``lift_out``), else a new
hold, else no lower than the palm's stop (``DescentGuard.rest``) and, there, which object the
hand rests on (``Steering._note_resting``). :func:`steer` runs those very tests in the same
order, on the same numbers, so it steers to the same target, keeps the same state and names
the same object (``tests/test_steer_core.py`` checks it on every tick of whole trials). The
formulas are the reference modules' docstrings (``app.teleop.lift_out``,
``app.teleop.guarded_descent``); in short, with ``n_k = r_k + s + c`` and
``z_k = h_k + b + c``:

    hand over k:     |x_xy - o_k,xy| < n_k                            (math.hypot)
    lift out:        (x_x, x_y, z_k + m) if x_z < z_k else (t_x, t_y, max(t_z, z_k))
    hold above k:    (t_x, t_y, z_k + HOVER_M)
    palm's stop:     (t_x, t_y, h_k - p + PALM_CLEAR_M) for a target below it

``math.hypot`` is CPython's ``vector_norm`` (scaled, squares kept exactly in two parts, one
correction step), reproduced by :func:`hypot2`: a plain ``sqrt(dx^2 + dy^2)`` differs from it
in the last bit now and then, which would move a decision at a threshold.

The state (``STATE``: the guard's ``held``, ``_cleared``, ``_clear_since``, ``palm_on``,
``palm_left`` and the trial's last TCP height) is a float array, ``-1`` for ``None`` (``NaN``
for no ``_clear_since``); the caller mirrors it into the guard when it changes.
"""

from __future__ import annotations

import math

import numpy as np

from app.compiled import jit
from app.norm_core import vector_norm
from app.teleop.guarded_descent import (
    CENTRED_M,
    HOVER_M,
    MARGIN_M,
    PAD_M,
    PALM_CLEAR_M,
    SETTLE_S,
    SINK_M,
)
from app.teleop.lift_out import CENTRE_M, LEAVING_M
from app.teleop.lift_out import MARGIN_M as LIFT_MARGIN_M

__all__ = ["CHANGED", "RESTING", "STATE", "STEERED", "hypot2", "steer"]

STATE = ("held", "cleared", "since_t", "since_x", "since_y", "palm_on", "palm_left", "last_z")
"""What :func:`steer`'s ``state`` holds, in order."""
STEERED = 1
"""Bit of :func:`steer`'s result: ``out[:3]`` is the target (else the user's target)."""
CHANGED = 2
"""Bit of :func:`steer`'s result: the guard's part of ``state`` changed."""
RESTING = 4
"""Bit of :func:`steer`'s result: the hand rests on an object (``out[3:6]`` names it)."""

# consts: what a trial's hand and scene fix (``pack_consts``)
_REACH_BELOW, _SLOT, _CLEARANCE, _PALM_ABOVE, _HX, _HY, _PARTS_LO, _LOW, _FLOOR, _NPARTS = range(10)


def pack_consts(
    *,
    reach_below: float,
    slot: float,
    clearance: float,
    palm_above: float,
    palm_half: tuple[float, float],
    parts: tuple[tuple[float, float, float], ...],
    parts_lo: float,
    low: float,
    floor: float,
) -> np.ndarray:
    """The fixed numbers of :func:`steer` in one array: the guard's hand, its parts (``(lo,
    h_x, h_y)`` each) and the reach's floor height."""
    head = (reach_below, slot, clearance, palm_above, *palm_half, parts_lo, low, floor)
    flat = [v for part in parts for v in part]
    return np.array((*head, float(len(parts)), *flat), dtype=np.float64)


@jit
def hypot2(a: float, b: float) -> float:
    """``math.hypot(a, b)`` as CPython gives it (``vector_norm``)."""
    d0, d1 = abs(a), abs(b)
    if math.isinf(d0) or math.isinf(d1):
        return math.inf
    if math.isnan(d0) or math.isnan(d1):
        return math.nan
    return vector_norm(d0, d1, 0.0)


@jit
def _clears(px: float, py: float, obj: np.ndarray, slot: float, margin: float) -> bool:
    """``guarded_descent._clears``."""
    return abs(py - obj[1]) <= slot - obj[4] - margin or abs(px - obj[0]) >= obj[2] + PAD_M + margin


@jit
def _both_clear(x: np.ndarray, t: np.ndarray, obj: np.ndarray, slot: float, margin: float) -> bool:
    """``guarded_descent._both_clear``."""
    return _clears(x[0], x[1], obj, slot, margin) and _clears(t[0], t[1], obj, slot, margin)


@jit
def _skipped(k: int, taking: int, fallen: np.ndarray) -> bool:
    """``k in (taking, *fallen)``."""
    if k == taking:
        return True
    for j in fallen:  # noqa: SIM110 - a loop numba compiles (no generator)
        if k == j:
            return True
    return False


@jit
def _around(
    x: np.ndarray, objects: np.ndarray, skip_k: int, fallen: np.ndarray, c: np.ndarray
) -> int:
    """``DescentGuard.around`` (``-1`` for ``None``), ``skip`` = ``(skip_k, *fallen)``."""
    slot = c[_SLOT]
    for k in range(objects.shape[0]):
        o = objects[k]
        if _skipped(k, skip_k, fallen):
            continue
        if hypot2(x[0] - o[0], x[1] - o[1]) >= o[2] + slot + c[_CLEARANCE]:
            continue
        if abs(x[1] - o[1]) <= slot - o[4] and abs(x[0] - o[0]) < o[2] + PAD_M:
            return k
    return -1


@jit
def _under_palm(
    x: np.ndarray, objects: np.ndarray, skip_k: int, fallen: np.ndarray, left: int, c: np.ndarray
) -> int:
    """``DescentGuard.under_palm`` (``-1`` for ``None``)."""
    k = _around(x, objects, skip_k, fallen, c)
    if k >= 0:
        return k
    hx, hy = c[_HX], c[_HY]
    for k in range(objects.shape[0]):
        o = objects[k]
        r = o[2] - MARGIN_M if k == left else o[2]
        if (
            not _skipped(k, skip_k, fallen)
            and abs(x[0] - o[0]) < r + hx
            and abs(x[1] - o[1]) < r + hy
        ):
            return k
    return -1


@jit
def _near(x: np.ndarray, o: np.ndarray, c: np.ndarray) -> bool:
    """``DescentGuard._near``."""
    r = o[2] + MARGIN_M
    return abs(x[0] - o[0]) < r + c[_HX] and abs(x[1] - o[1]) < r + c[_HY]


@jit
def _keep(
    k: int,
    x: np.ndarray,
    t: np.ndarray,
    objects: np.ndarray,
    taking: int,
    fallen: np.ndarray,
    state: np.ndarray,
    out: np.ndarray,
    c: np.ndarray,
    now: float,
) -> bool:
    """``DescentGuard._keep``: ``True`` with the hold in ``out[:3]``, ``False`` once it lets go."""
    if not _skipped(k, taking, fallen):
        o = objects[k]
        slot, clearance = c[_SLOT], c[_CLEARANCE]
        z_k = o[3] + c[_REACH_BELOW] + clearance
        if hypot2(x[0] - o[0], x[1] - o[1]) < o[2] + slot + clearance + MARGIN_M and t[2] < z_k:
            if not _both_clear(x, t, o, slot, 0.0):
                state[2] = state[3] = state[4] = math.nan
                out[0], out[1], out[2] = t[0], t[1], z_k + HOVER_M
                return True
            if math.isnan(state[2]) or hypot2(x[0] - state[3], x[1] - state[4]) > MARGIN_M:
                state[2], state[3], state[4] = now, x[0], x[1]  # a hand sweeping across restarts
            if now - state[2] < SETTLE_S:
                out[0], out[1], out[2] = t[0], t[1], z_k + HOVER_M
                return True
            state[1] = k  # centred: the hand comes down around it
    state[0] = -1.0
    state[2] = state[3] = state[4] = math.nan
    return False


@jit
def _hold(
    x: np.ndarray,
    t: np.ndarray,
    objects: np.ndarray,
    taking: int,
    fallen: np.ndarray,
    state: np.ndarray,
    out: np.ndarray,
    c: np.ndarray,
) -> bool:
    """``DescentGuard.steer`` holding nothing: ``True`` with a new hold in ``out[:3]``."""
    reach_below, slot, clearance = c[_REACH_BELOW], c[_SLOT], c[_CLEARANCE]
    cleared = int(state[1])
    for k in range(objects.shape[0]):
        o = objects[k]
        over = hypot2(x[0] - o[0], x[1] - o[1]) < o[2] + slot + clearance
        if k == cleared and not over:
            state[1] = -1.0  # the hand has left the object it came down on
        z_k = o[3] + reach_below + clearance
        if not over or t[2] >= z_k or x[2] - reach_below < o[3] - SINK_M:
            continue
        if _skipped(k, taking, fallen):
            continue
        loose = MARGIN_M if k == cleared else 0.0
        if _both_clear(x, t, o, slot, -loose):
            continue
        state[0], state[1] = k, -1.0
        state[2] = state[3] = state[4] = math.nan
        out[0], out[1], out[2] = t[0], t[1], z_k + HOVER_M
        return True
    return False


@jit
def _lift_out(
    x: np.ndarray,
    t: np.ndarray,
    objects: np.ndarray,
    taking: int,
    fallen: np.ndarray,
    out: np.ndarray,
    c: np.ndarray,
) -> bool:
    """``lift_out``: ``True`` with the target in ``out[:3]``, ``False`` for ``None``."""
    clearance = c[_CLEARANCE]
    for k in range(objects.shape[0]):
        if _skipped(k, taking, fallen):
            continue
        o = objects[k]
        near = o[2] + c[_SLOT] + clearance
        d_x = hypot2(x[0] - o[0], x[1] - o[1])
        if d_x >= near:
            continue
        d_t = hypot2(t[0] - o[0], t[1] - o[1])
        if d_t < near and d_t <= (CENTRE_M if d_x < CENTRE_M else d_x) + LEAVING_M:
            continue
        floor = o[3] + c[_REACH_BELOW] + clearance
        if x[2] < floor:
            out[0], out[1], out[2] = x[0], x[1], floor + LIFT_MARGIN_M
        else:
            out[0], out[1], out[2] = t[0], t[1], floor if floor > t[2] else t[2]
        return True
    return False


@jit
def _rest(
    x: np.ndarray,
    t: np.ndarray,
    objects: np.ndarray,
    taking: int,
    fallen: np.ndarray,
    state: np.ndarray,
    c: np.ndarray,
) -> tuple[int, float]:
    """``DescentGuard.rest``: ``(k, rest_z)``, ``k = -1`` for ``None``."""
    held, left = int(state[5]), int(state[6])
    if left >= 0 and not _near(x, objects[left], c):
        left = -1  # the hand is clear of the footprint it left
    k = _under_palm(x, objects, taking, fallen, left, c)
    tz = t[2]
    rest_z = -math.inf if k < 0 else objects[k, 3] - c[_PALM_ABOVE] + PALM_CLEAR_M
    nparts = int(c[_NPARTS])
    if nparts > 0:
        above = rest_z if rest_z > tz else tz
        for j in range(objects.shape[0]):
            o = objects[j]
            if o[3] - c[_PARTS_LO] + PALM_CLEAR_M <= above or _skipped(j, taking, fallen):
                continue
            r = o[2] - MARGIN_M if j == left else o[2]
            for m in range(nparts):
                lo, hx, hy = c[_NPARTS + 1 + 3 * m], c[_NPARTS + 2 + 3 * m], c[_NPARTS + 3 + 3 * m]
                z = o[3] - lo + PALM_CLEAR_M
                if z > above and abs(x[0] - o[0]) < r + hx and abs(x[1] - o[1]) < r + hy:
                    above = rest_z = z
                    k = j
    if k < 0:
        state[5] = -1.0
        if held >= 0 and objects[held, 3] < c[_LOW] and _near(x, objects[held], c):
            left = held  # it left the footprint the stop held it over: let go
        state[6] = left
        return -1, rest_z
    state[6] = -1.0 if k == left else left
    if tz >= rest_z:
        state[5] = -1.0
        return -1, rest_z
    state[5] = k
    return k, rest_z


@jit
def steer(
    x: np.ndarray,
    t: np.ndarray,
    objects: np.ndarray,
    taking: int,
    fallen: np.ndarray,
    state: np.ndarray,
    out: np.ndarray,
    c: np.ndarray,
    now: float,
) -> int:
    """One tick of the open hand's steering (``Steering.reference`` after its closed-gripper
    test): the TCP ``x`` (3,), the user's target ``t`` (3,), the objects as footprints
    ``(n, 5)`` (``Footprint``), the object the robot takes the hand to (``taking``, ``-1``:
    none), the fallen objects' indices, the ``state`` (``STATE``), the fixed numbers
    ``c`` (:func:`pack_consts`) at time ``now``. Writes the target ``out[:3]`` when it steers,
    and ``out[3:6]``: the object the hand rests on (``-1``: none), whether centred (0/1) and
    its offset along x (left as it was when it rests on none). Returns ``STEERED``,
    ``CHANGED`` and ``RESTING`` bits."""
    before = state[:7].copy()
    out[3] = -1.0
    out[4] = 0.0
    steered = False
    if state[0] >= 0.0:  # a hold is kept until the guard lets go
        steered = _keep(int(state[0]), x, t, objects, taking, fallen, state, out, c, now)
    if not steered:
        steered = _lift_out(x, t, objects, taking, fallen, out, c)
    if not steered:
        steered = _hold(x, t, objects, taking, fallen, state, out, c)
    if not steered:
        k, rest_z = _rest(x, t, objects, taking, fallen, state, c)
        if k >= 0:
            out[0], out[1], out[2] = t[0], t[1], rest_z
            steered = True
        _note_resting(x, t[2], k, rest_z, objects, fallen, state, out, c)
    changed = False
    for i in range(7):
        a, b = before[i], state[i]
        if a != b and not (math.isnan(a) and math.isnan(b)):
            changed = True
    resting = RESTING if out[3] >= 0.0 else 0
    return (STEERED if steered else 0) | (CHANGED if changed else 0) | resting


@jit
def _note_resting(
    x: np.ndarray,
    target_z: float,
    rest_k: int,
    rest_z: float,
    objects: np.ndarray,
    fallen: np.ndarray,
    state: np.ndarray,
    out: np.ndarray,
    c: np.ndarray,
) -> None:
    """``Steering._note_resting``: the object the hand rests on into ``out[3:6]``."""
    last = state[7]
    state[7] = x[2]
    if rest_k >= 0:
        if x[2] > rest_z + 0.005:
            return  # still coming down to the palm's stop
    else:
        if target_z > c[_FLOOR] + 1e-6:
            return  # the input does not ask it lower than it goes
        if x[2] > target_z + 0.005 and abs(x[2] - last) >= 2e-4:
            return  # still coming down
    k = _under_palm(x, objects, -1, fallen, int(state[6]), c)
    if k < 0 and rest_k >= 0:
        k = rest_k  # a part of the hand above the palm stopped beside a tall object
    if k >= 0:
        offset = x[0] - objects[k, 0]
        out[3] = k
        out[5] = offset
        if abs(offset) <= CENTRED_M and _around(x, objects, -1, fallen, c) == k:
            out[4] = 1.0


def warm_up() -> None:
    """Compile (or load) :func:`steer` for the types a trial passes."""
    objects = np.array([[0.5, 0.0, 0.04, 0.1, 0.03]])
    state = np.array([-1.0, -1.0, math.nan, math.nan, math.nan, -1.0, -1.0, math.inf])
    consts = pack_consts(
        reach_below=0.05,
        slot=0.04,
        clearance=0.01,
        palm_above=0.06,
        palm_half=(0.02, 0.05),
        parts=((0.1, 0.03, 0.04),),
        parts_lo=0.1,
        low=0.2,
        floor=0.0,
    )
    x = np.array([0.5, 0.0, 0.2])
    steer(x, x.copy(), objects, -1, np.zeros(0, dtype=np.int64), state, np.zeros(6), consts, 0.0)

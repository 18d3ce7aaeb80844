"""The grasp policy's tick compiled: carrot, clearance geometry and damped least squares.

The same steps as :class:`~app.blending.policy_grasp.GraspApproachPolicy`'s reference methods
(its module docstring has the maths), written over arrays for numba, operation for operation
in the same order, so ``P`` comes out bit for bit the same (``tests/test_tick_fast_path.py``):

    v = min(1, s / |c - x|) (c - x),   w = min(1, s_w / |e|) e,   e = log(R_g R^T)
    dq = z + J^T (J J^T + lambda^2 I)^-1 ([v; w] - J z)
    P = clip(Q + min(1, max_step / |dq|) dq)

Python's ``min``/``max`` are spelt out as the comparisons they make (``max(a, b)`` is ``b if
b > a else a``), so ties and signed zeros come out as in the reference.

Packed inputs (built once per goal set by the policy):

- ``goal`` (21,): grasp point ``g``, pre-grasp point ``p``, approach axis ``a``, the grasp's
  ``x`` and ``y`` axes (3 each), then ``standoff, top, tol_entry, tol_deep, slot_reach, near``;
- ``objects`` (n, 4): ``x, y, radius, top`` of each goal's envelope;
- ``layers`` (L, 9): ``lo, reach, cx, cy, hx, hy, hd, hmax, turns`` per hand layer;
- ``params`` (9,): ``drop, clearance, tcp_step, approach_step, rotation_step, posture_step,
  max_step, turns (0/1), limits (0/1)``.
"""

from __future__ import annotations

import math

import numpy as np

from app.compiled import dls, jit

__all__ = ["grasp_finish", "grasp_step", "grasp_twist", "rotation_log", "warm_up"]

_SQRT_HALF = math.sqrt(0.5)
# policy_grasp's thresholds (this module cannot import it; tests/test_tick_fast_path.py checks them)
_ROTATION_TOL = 0.1
_ALIGN_MARGIN = 0.002
_HOLD_WIDEN = 0.003
# a frame row: bottom, centre offset (x, y), inflation, then 4 x (n_x, n_y, support)
_FRAME = 16
# span cache per (object, layer): state (0 unknown, 1 no overlap, 2 overlap), s0, s1
_UNKNOWN, _NONE, _SPAN = 0.0, 1.0, 2.0


@jit
def rotation_log(m: np.ndarray) -> tuple[float, float, float]:
    """``log(M)`` of a rotation matrix (3, 3) as a rotation vector ``theta k``."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    h = 0.5 * (tr - 1.0)
    h = h if h < 1.0 else 1.0
    c = h if h > -1.0 else -1.0
    wx, wy, wz = m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]
    s = 0.5 * math.sqrt(wx * wx + wy * wy + wz * wz)  # sin(theta)
    theta = math.atan2(s, c)
    if s > 1e-6:
        f = theta / (2.0 * s)
        return wx * f, wy * f, wz * f
    if c > 0.0:  # theta near 0: log = vee(M - M^T) / 2
        return 0.5 * wx, 0.5 * wy, 0.5 * wz
    # theta near pi: the axis from the diagonal (M = 2 k k^T - I), signs from the largest entry
    kk = np.empty(3)
    for i in range(3):
        d = 0.5 * (m[i, i] + 1.0)
        kk[i] = math.sqrt(d if d > 0.0 else 0.0)
    i = 0
    for j in range(1, 3):
        if kk[j] > kk[i]:
            i = j
    axis = np.zeros(3)
    axis[i] = kk[i]
    for j in range(3):
        if j != i:
            axis[j] = 0.5 * (m[i, j] + m[j, i]) / (2.0 * kk[i])
    return axis[0] * theta, axis[1] * theta, axis[2] * theta


@jit
def _frames(q: np.ndarray, rot: np.ndarray, layers: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Each layer in the world's xy plane (``GraspApproachPolicy._frames``)."""
    r00, r01, r02 = rot[0, 0], rot[0, 1], rot[0, 2]
    r10, r11, r12 = rot[1, 0], rot[1, 1], rot[1, 2]
    tilt = math.sqrt(r02 * r02 + r12 * r12)
    ct = st = 0.0
    if params[7] != 0.0:
        turn = -q[q.shape[0] - 1]
        ct, st = math.cos(turn), math.sin(turn)
    m = params[1]
    out = np.empty((layers.shape[0], _FRAME))
    for i in range(layers.shape[0]):
        lo, reach, cx, cy = layers[i, 0], layers[i, 1], layers[i, 2], layers[i, 3]
        hx, hy, hd, hmax = layers[i, 4], layers[i, 5], layers[i, 6], layers[i, 7]
        if layers[i, 8] != 0.0:
            ux, uy = r00 * ct + r01 * st, r10 * ct + r11 * st
            vx, vy = r01 * ct - r00 * st, r11 * ct - r10 * st
        else:
            ux, uy, vx, vy = r00, r10, r01, r11
        f = out[i]
        f[0] = lo - hmax * tilt - m
        f[1] = cx * ux + cy * vx
        f[2] = cx * uy + cy * vy
        f[3] = m + reach * tilt
        f[4], f[5], f[6] = ux, uy, hx
        f[7], f[8], f[9] = vx, vy, hy
        f[10], f[11], f[12] = (ux + vx) * _SQRT_HALF, (uy + vy) * _SQRT_HALF, hd
        f[13], f[14], f[15] = (ux - vx) * _SQRT_HALF, (uy - vy) * _SQRT_HALF, hd
    return out


@jit
def _overlap(
    px: float, py: float, mx: float, my: float, f: np.ndarray, rho: float
) -> tuple[bool, float, float]:
    """``(overlaps, s0, s1)``: ``policy_grasp._overlap`` over the frame row ``f``'s slabs."""
    s0, s1 = 0.0, 1.0
    for d in range(4):
        nx, ny, h = f[4 + 3 * d], f[5 + 3 * d], f[6 + 3 * d]
        pn, mn = px * nx + py * ny, mx * nx + my * ny
        h += rho
        if -1e-12 < mn < 1e-12:
            if pn > h or pn < -h:
                return False, s0, s1
            continue
        t0, t1 = (pn - h) / mn, (pn + h) / mn
        if t0 > t1:
            t0, t1 = t1, t0
        if t0 > s0:
            s0 = t0
        if t1 < s1:
            s1 = t1
        if s0 > s1:
            return False, s0, s1
    return True, s0, s1


@jit
def _swept(
    spans: np.ndarray,
    j: int,
    i: int,
    px: float,
    py: float,
    mx: float,
    my: float,
    f: np.ndarray,
    rho: float,
) -> tuple[bool, float, float]:
    """``_overlap``, kept in ``spans[j, i]`` for the sweep (the same ``a``, the same
    horizontal motion)."""
    c = spans[j, i]
    if c[0] == _UNKNOWN:
        hit, s0, s1 = _overlap(px, py, mx, my, f, rho)
        c[0], c[1], c[2] = (_SPAN if hit else _NONE), s0, s1
    return c[0] == _SPAN, c[1], c[2]


@jit
def _freedom(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    frames: np.ndarray,
    objects: np.ndarray,
    skip: int,
    m: float,
    spans: np.ndarray,
) -> float:
    """How much of the TCP segment ``a -> b`` the hand may take (``_freedom``); ``skip``: an
    object's index, or the number of objects for none. ``spans`` kept for the sweep (cleared,
    it stands for the reference's unshared test: one test works out each span once)."""
    low = az if az < bz else bz
    rising = bz >= az
    mx, my = bx - ax, by - ay
    free = 1.0
    for j in range(objects.shape[0]):
        if j == skip:
            continue
        cx, cy, radius, top = objects[j, 0], objects[j, 1], objects[j, 2], objects[j, 3]
        for i in range(frames.shape[0]):
            f = frames[i]
            bottom, ox, oy, grow = f[0], f[1], f[2], f[3]
            need = top - bottom
            if low >= need:
                continue
            hit, s0, s1 = _swept(spans, j, i, cx - ax - ox, cy - ay - oy, mx, my, f, radius + grow)
            if not hit:
                continue
            if az + s0 * (bz - az) >= need and az + s1 * (bz - az) >= need:
                continue
            if s0 > 0.0:
                return 0.0
            ux, uy, hu, vx, vy, hv = f[4], f[5], f[6], f[7], f[8], f[9]
            px, py = cx - ax - ox, cy - ay - oy
            du, dv = px * ux + py * uy, px * vx + py * vy
            du -= hu if du > hu else (-hu if du < -hu else du)
            dv -= hv if dv > hv else (-hv if dv < -hv else dv)
            if du * du + dv * dv > radius * radius and (
                (mx * ux + my * uy) * du + (mx * vx + my * vy) * dv <= 0.0
            ):
                continue
            if rising and az > need - m:
                share_ = (az - need + m) / m
                free = share_ if share_ < free else free
                continue
            return 0.0
    return free


@jit
def _pass_height(
    ax: float,
    ay: float,
    bx: float,
    by: float,
    frames: np.ndarray,
    objects: np.ndarray,
    skip: int,
    spans: np.ndarray,
) -> float:
    """The lowest TCP height at which the hand passes from above ``a`` to above ``b``
    (``_pass_height``; ``skip`` and ``spans`` as in ``_freedom``)."""
    mx, my = bx - ax, by - ay
    height = -math.inf
    for j in range(objects.shape[0]):
        if j == skip:
            continue
        cx, cy, radius, top = objects[j, 0], objects[j, 1], objects[j, 2], objects[j, 3]
        for i in range(frames.shape[0]):
            f = frames[i]
            need = top - f[0]
            if need <= height:
                continue
            hit, _, _ = _swept(
                spans, j, i, cx - ax - f[1], cy - ay - f[2], mx, my, f, radius + f[3]
            )
            if hit:
                height = need
    return height


@jit
def _toward(
    xs: np.ndarray, cx: float, cy: float, cz: float, f: float
) -> tuple[float, float, float]:
    """The carrot with only the share ``f`` of its horizontal offset from ``xs``."""
    if f >= 1.0:
        return cx, cy, cz
    return xs[0] + f * (cx - xs[0]), xs[1] + f * (cy - xs[1]), cz


@jit
def _carrot(
    q: np.ndarray,
    xs: np.ndarray,
    rot: np.ndarray,
    goal: np.ndarray,
    k: int,
    rot_err: float,
    held: bool,
    objects: np.ndarray,
    layers: np.ndarray,
    params: np.ndarray,
) -> tuple[float, float, float, bool]:
    """``(carrot, in transit)`` from the TCP at ``xs`` toward goal ``k``
    (``GraspApproachPolicy._carrot``; the TCP step is ``tcp_step`` throughout)."""
    drop, m, tcp_step, approach_step = params[0], params[1], params[2], params[3]
    g0, g1, g2 = goal[0], goal[1], goal[2]
    a0, a1, a2 = goal[6], goal[7], goal[8]
    standoff, top, tol_entry, tol_deep = goal[15], goal[16], goal[17], goal[18]
    slot_reach, near = goal[19], goal[20]
    dx, dy, dz = xs[0] - g0, xs[1] - g1, xs[2] - g2
    above = -(dx * a0 + dy * a1 + dz * a2)
    ex = dx * goal[9] + dy * goal[10] + dz * goal[11]
    ey = dx * goal[12] + dy * goal[13] + dz * goal[14]
    spans = np.zeros((objects.shape[0], layers.shape[0], 3))
    frames = np.empty((0, _FRAME))
    have_frames = False
    widen = _HOLD_WIDEN if held else 0.0
    if rot_err <= _ROTATION_TOL + (0.05 if held else 0.0):
        tol = (tol_entry if above >= top + drop else tol_deep) + widen
        sink = approach_step if above <= standoff + 0.005 else tcp_step
        h = above - sink if above > sink else 0.0
        d0, d1, d2 = g0 - h * a0, g1 - h * a1, g2 - h * a2
        if ex * ex + ey * ey <= tol * tol:
            return d0, d1, d2, False
        if above < standoff:
            frames = _frames(q, rot, layers, params)
            have_frames = True
            if abs(ey) + abs(ex) * rot_err <= tol and abs(ex) <= slot_reach:
                # toward down's xy: the three tests share their spans
                f = _freedom(xs[0], xs[1], xs[2], d0, d1, d2, frames, objects, k, m, spans)
                if f >= 1.0:
                    return d0, d1, d2, False
                floor = _pass_height(xs[0], xs[1], d0, d1, frames, objects, k, spans)
                s2 = floor if floor > d2 else d2
                f = _freedom(xs[0], xs[1], xs[2], d0, d1, s2, frames, objects, k, m, spans)
                if f > 0.0:
                    c0, c1, c2 = _toward(xs, d0, d1, s2, f)
                    return c0, c1, c2, False
            if (
                above - drop >= top + (0.0 if held else _ALIGN_MARGIN)
                and ex * ex + ey * ey <= near * near
            ):
                l0, l1, l2 = g0 - above * a0, g1 - above * a1, g2 - above * a2
                spans[:, :, 0] = _UNKNOWN  # a test of its own
                f = _freedom(xs[0], xs[1], xs[2], l0, l1, l2, frames, objects, k, m, spans)
                if f > 0.0:
                    c0, c1, c2 = _toward(xs, l0, l1, l2, f)
                    return c0, c1, c2, False
    if not have_frames:
        frames = _frames(q, rot, layers, params)
    p0, p1, p2 = goal[3], goal[4], goal[5]
    spans[:, :, 0] = _UNKNOWN  # toward p's xy: a new sweep
    none = objects.shape[0]  # skip no object
    f = _freedom(xs[0], xs[1], xs[2], p0, p1, p2, frames, objects, none, m, spans)
    if f > 0.0:
        c0, c1, c2 = _toward(xs, p0, p1, p2, f)
        return c0, c1, c2, True
    ph = _pass_height(xs[0], xs[1], p0, p1, frames, objects, none, spans)
    zt = ph if ph > p2 else p2
    f = (
        1.0
        if xs[2] >= zt
        else _freedom(xs[0], xs[1], xs[2], p0, p1, zt, frames, objects, none, m, spans)
    )
    c0, c1, c2 = _toward(xs, p0, p1, zt, f)
    return c0, c1, c2, True


@jit
def grasp_step(
    q: np.ndarray,
    x: np.ndarray,
    rot: np.ndarray,
    jac: np.ndarray,
    goal: np.ndarray,
    goal_rot: np.ndarray,
    posture: np.ndarray,
    k: int,
    held: bool,
    objects: np.ndarray,
    layers: np.ndarray,
    params: np.ndarray,
    lam2: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> tuple[np.ndarray, bool, int]:
    """``(P, in transit, LAPACK info)`` from ``Q`` toward goal ``k`` (``GraspApproachPolicy.
    step``); ``posture`` empty when the goal has none; ``lower``/``upper`` read only when
    ``params[8]``."""
    e = rotation_log(np.dot(goal_rot, rot.T))
    twist, z, pull, transit = grasp_twist(
        q, x, rot, e, goal, posture, k, held, objects, layers, params
    )
    dq, info = dls(jac, twist, z, pull, lam2)
    return grasp_finish(q, dq, np.dot(dq, dq), params, lower, upper), transit, info


@jit
def grasp_twist(
    q: np.ndarray,
    x: np.ndarray,
    rot: np.ndarray,
    e: tuple[float, float, float],
    goal: np.ndarray,
    posture: np.ndarray,
    k: int,
    held: bool,
    objects: np.ndarray,
    layers: np.ndarray,
    params: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, bool, bool]:
    """``([v; w], posture pull z, whether to pull, in transit)`` toward goal ``k``, ``e =
    log(R_g R^T)``."""
    e0, e1, e2 = e
    rot_err = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    c0, c1, c2, transit = _carrot(q, x, rot, goal, k, rot_err, held, objects, layers, params)
    speed, rotation_step, posture_step = params[2], params[4], params[5]
    v0, v1, v2 = c0 - x[0], c1 - x[1], c2 - x[2]
    n = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    sv = speed / n if n > speed else 1.0
    sw = rotation_step / rot_err if rot_err > rotation_step else 1.0
    twist = np.array((sv * v0, sv * v1, sv * v2, sw * e0, sw * e1, sw * e2))
    pull = transit and posture.shape[0] > 0 and posture_step > 0.0
    z = np.empty(0)
    if pull:
        z = posture - q
        z *= posture_step
    return twist, z, pull, transit


@jit
def grasp_finish(
    q: np.ndarray,
    dq: np.ndarray,
    dq2: float,
    params: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> np.ndarray:
    """``clip(Q + min(1, max_step / |dq|) dq)`` (``dq2 = |dq|^2``; ``dq`` overwritten: it
    becomes ``P``)."""
    mag = math.sqrt(dq2)
    if mag > params[6]:
        dq *= params[6] / mag
    dq += q
    if params[8] != 0.0:
        for i in range(dq.shape[0]):
            lo = dq[i] if dq[i] >= lower[i] else lower[i]  # np.maximum, then np.minimum
            dq[i] = lo if lo <= upper[i] else upper[i]
    return dq


def warm_up() -> None:
    """Compile :func:`grasp_step` (or load it from numba's cache) with the argument types of a
    tick, on a dummy arm (a hand of one layer, two objects, limits)."""
    z = np.zeros
    grasp_step(
        z(7),
        z(3),
        np.eye(3),
        z((6, 7)),
        z(21),
        np.eye(3),
        z(7),
        0,
        False,
        z((2, 4)),
        z((1, 9)),
        np.ones(9),
        np.eye(6),
        -np.ones(7),
        np.ones(7),
    )

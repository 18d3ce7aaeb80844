"""A grasping policy: pre-grasp, approach along the gripper axis, and a hand that clears the scene.

From any configuration ``Q`` the robot's next configuration ``P`` moves the tool centre point
(TCP, at ``x``, rotation ``R``) toward a carrot ``c`` and the gripper toward the goal's grasp
rotation ``R_g``, by one damped-least-squares step:

    v = min(1, s / |c - x|) (c - x),   w = min(1, s_w / |e|) e,   e = log(R_g R^T)
    dq = z + J^T (J J^T + lambda^2 I)^-1 ([v; w] - J z),  z = k_n dt (q_g - Q) in transit, else 0
    P = Q + min(1, max_step / |dq|) dq     (clipped to the joint limits)

The carrot is what a pick-and-place robot does, chosen afresh each tick from where the hand is
now (a feedback policy: the user may have moved the arm anywhere):

1. in the goal's approach corridor (the TCP within ``tol`` of the approach axis, the gripper
   within ``ROTATION_TOL`` of the grasp rotation): ``c = g - max(0, h - s) a``, the point of
   the axis one step ``s`` nearer the grasp point ``g`` than the TCP's height ``h`` above it:
   down the gripper axis ``a``, at ``approach_speed`` below the pre-grasp point, to ``g``,
   where the fingers straddle the object and the policy stops;
2. else ``c = p``, the pre-grasp point ``g - standoff a`` (fingertips above the object's top),
   if the straight TCP segment ``x -> p`` keeps the hand clear of every object;
3. else ``c = (p_x, p_y, z_t)``, above the pre-grasp point at the height ``z_t`` at which the
   hand passes over everything between, if the segment there is clear;
4. else ``c = (x_x, x_y, z_t)``: straight up first.

Clearance: the hand (fingers, hand, wrist links: the parts that collide) is a stack of layers,
each a box in the TCP frame between heights ``lo`` and ``hi`` above the TCP; a layer on the link
before the last joint turns by ``-q_7`` about the TCP axis. Each object is an upright cylinder
(its goal's envelope). A TCP segment ``A -> B`` (orientation held) is clear of object ``j`` when,
for every layer, over the part of the segment where the layer's box, inflated by the object's
radius plus ``clearance``, covers the object's axis (an interval of the segment found by slabs),
the layer's bottom stays ``clearance`` above the object's top. The model assumes an approach
axis near vertical (top-down grasps); a tilted hand inflates every layer by its tilt.

Pure numpy: the arm comes in as an :class:`ArmModel` (a ``pose_jacobian`` callable and plain
numbers), so this module imports no kinematics library.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from scipy.linalg.lapack import dposv

from ._checks import positive
from .errors import InvalidInputError
from .goals import GoalSet

__all__ = ["ArmModel", "GraspApproachPolicy", "HandLayer", "rotation_log"]

ROTATION_TOL = 0.1
"""rad: the gripper must be this close to the grasp rotation to start the approach."""
ROTATION_SPEED = 1.0
"""rad/s: how fast the gripper turns toward the grasp rotation."""
POSTURE_GAIN = 1.0
"""1/s: the null-space pull toward the goal's grasp configuration while in transit."""
TOL_MIN, TOL_MAX = 0.002, 0.01
"""m: the approach corridor's radius is half the fingers' slack around the object (three
quarters once they straddle it), within these bounds."""


@dataclass(frozen=True)
class HandLayer:
    """One collision part of the hand: a box in the TCP frame.

    ``lo``, ``hi``: heights of its bottom and top above the TCP, measured back along the
    approach axis (the fingertips have ``lo < 0``); ``center``, ``half``: the box's centre
    and half-extents along the TCP's x and y axes (metres). ``turns``: the part sits on the
    link before the last joint, so it turns by ``-q[-1]`` about the TCP axis; then ``center``
    and ``half`` are in the TCP frame at ``q[-1] = 0``.
    """

    lo: float
    hi: float
    center: tuple[float, float]
    half: tuple[float, float]
    turns: bool = False


@dataclass(frozen=True, eq=False)
class ArmModel:
    """What a grasping policy needs of the arm and its workspace.

    ``pose_jacobian(q) -> (x (3,), R (3, 3), J (6, dof))``: the TCP's position, rotation and
    world-aligned Jacobian (linear rows first). ``layers``: the hand's collision parts;
    ``slot``: half the gap between the open fingers (m); ``table_z``: the table top;
    ``lower``/``upper``: joint limits (``P`` is clipped to them), or ``None``.
    """

    pose_jacobian: Callable[[np.ndarray], tuple[Any, Any, Any]]
    layers: tuple[HandLayer, ...]
    slot: float
    table_z: float = 0.0
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    @property
    def reach_below(self) -> float:
        """How far the fingertips reach below the TCP (m, >= 0)."""
        return max(0.0, -min((layer.lo for layer in self.layers), default=0.0))


class _Goal(NamedTuple):
    g: tuple[float, float, float]  # grasp point
    p: tuple[float, float, float]  # pre-grasp point
    a: tuple[float, float, float]  # approach axis (TCP z at the grasp)
    rotation: np.ndarray  # R_g
    standoff: float
    top: float  # object's top above the grasp point
    tol_entry: float  # corridor radius with the fingers above the object
    tol_deep: float  # ... once they straddle it
    posture: np.ndarray | None  # q_g


class GraspApproachPolicy:
    """Pre-grasp, approach along the gripper axis, stop at the grasp; the hand clears the scene.

    ``step(Q, k)`` with ``k`` the goal's index in the :class:`GoalSet` last given to
    :meth:`set_goals` (``target_space = "goal"``); the goals need orientations, standoffs and
    envelopes (``app.robot.build_scene`` makes them).

    Args:
        arm: the arm's kinematics and hand geometry.
        max_step: ``|P - Q|`` limit per tick (configuration units), as the straight line's.
        tcp_step: TCP travel per tick in transit (metres).
        approach_step: TCP travel per tick from the pre-grasp point to the grasp.
        clearance: the hand keeps this far (metres) beside and above every object but the
            one it straddles.
        rotation_step: gripper rotation per tick (rad).
        damping: ``lambda`` of the damped least squares.
        posture_step: null-space gain per tick toward the grasp configuration.
    """

    target_space = "goal"

    def __init__(
        self,
        *,
        arm: ArmModel,
        max_step: float,
        tcp_step: float,
        approach_step: float,
        clearance: float = 0.02,
        rotation_step: float = 0.01,
        damping: float = 1e-3,
        posture_step: float = 0.01,
    ) -> None:
        if not isinstance(arm, ArmModel):
            raise InvalidInputError(f"arm: expected an ArmModel, got {type(arm).__name__}")
        if not callable(arm.pose_jacobian):
            raise InvalidInputError("arm.pose_jacobian: expected a callable q -> (x, R, J)")
        if not arm.layers:
            raise InvalidInputError("arm.layers: give the hand's collision parts (HandLayer)")
        self.arm = arm
        self.max_step = positive(max_step, name="max_step")
        self.tcp_step = positive(tcp_step, name="tcp_step")
        self.approach_step = positive(approach_step, name="approach_step")
        self.clearance = positive(clearance, name="clearance", allow_zero=True)
        self.rotation_step = positive(rotation_step, name="rotation_step")
        self.damping = positive(damping, name="damping")
        self.posture_step = positive(posture_step, name="posture_step", allow_zero=True)
        self._pose_jacobian = arm.pose_jacobian
        self._slot = positive(arm.slot, name="arm.slot")
        self._drop = arm.reach_below
        self._layers = tuple(
            (
                float(layer.lo),
                float(layer.hi),
                float(layer.center[0]),
                float(layer.center[1]),
                float(layer.half[0]),
                float(layer.half[1]),
                bool(layer.turns),
            )
            for layer in arm.layers
        )
        self._turns = any(layer.turns for layer in arm.layers)
        self._lam2 = self.damping**2 * np.eye(6)
        self._lower = arm.lower
        self._upper = arm.upper
        self._goals: tuple[_Goal, ...] = ()
        self._objects: tuple[tuple[float, float, float, float], ...] = ()

    # ---- goals -------------------------------------------------------------------------
    def set_goals(self, goals: GoalSet) -> None:
        """Take the grasp frames (and the objects to clear) of ``goals``; per goal work is done
        here, once, not per tick."""
        if goals.orientations is None or goals.standoffs is None or goals.envelopes is None:
            raise InvalidInputError(
                "goals: the grasp policy needs grasp frames: orientations, standoffs and"
                " envelopes (app.robot.build_scene gives them)"
            )
        rotations = goals.rotations()
        pregrasp = goals.pregrasp_positions()
        out = []
        for k in range(len(goals)):
            _, top, half_width = goals.envelopes[k].tolist()
            slack = self._slot - half_width
            out.append(
                _Goal(
                    g=tuple(goals.positions[k].tolist()),
                    p=tuple(pregrasp[k].tolist()),
                    a=tuple(rotations[k][:, 2].tolist()),
                    rotation=rotations[k].copy(),
                    standoff=float(goals.standoffs[k]),
                    top=top,
                    tol_entry=min(TOL_MAX, max(TOL_MIN, 0.5 * slack)),
                    tol_deep=min(TOL_MAX, max(TOL_MIN, 0.75 * slack)),
                    posture=None
                    if goals.configurations is None
                    else goals.configurations[k].copy(),
                )
            )
        self._goals = tuple(out)
        self._objects = tuple(
            (float(pos[0]), float(pos[1]), float(env[0]), float(pos[2] + env[1]))
            for pos, env in zip(goals.positions, goals.envelopes, strict=True)
        )

    # ---- the step ------------------------------------------------------------------------
    def step(self, q: np.ndarray, target: Any) -> np.ndarray:
        """``P``, the next configuration from ``Q`` toward goal ``target`` (an index)."""
        if not self._goals:
            raise InvalidInputError("set_goals(goals) must be called before step(Q, goal)")
        goal = self._goals[int(target)]
        x, rot, jac = self._pose_jacobian(q)
        xs = x.tolist()
        e = rotation_log((goal.rotation @ rot.T).tolist())
        rot_err = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        carrot, speed, transit = self._carrot(q, xs, rot, goal, rot_err)
        v = [carrot[0] - xs[0], carrot[1] - xs[1], carrot[2] - xs[2]]
        n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        sv = speed / n if n > speed else 1.0
        sw = self.rotation_step / rot_err if rot_err > self.rotation_step else 1.0
        twist = np.array(
            (sv * v[0], sv * v[1], sv * v[2], sw * e[0], sw * e[1], sw * e[2]), dtype=np.float64
        )
        z = None
        if transit and goal.posture is not None and self.posture_step > 0.0:
            z = goal.posture - q
            z *= self.posture_step
            twist -= jac @ z
        a = jac @ jac.T
        a += self._lam2
        _, y, info = dposv(a, twist, overwrite_a=1, overwrite_b=1)
        if info != 0:  # pragma: no cover - J J^T + lambda^2 I is positive definite
            raise InvalidInputError("arm.pose_jacobian: returned a Jacobian that is not finite")
        dq = jac.T @ y
        if z is not None:
            dq += z
        m = math.sqrt(float(dq.dot(dq)))
        if m > self.max_step:
            dq *= self.max_step / m
        dq += q
        if self._lower is not None and self._upper is not None:
            np.minimum(np.maximum(dq, self._lower, out=dq), self._upper, out=dq)
        return dq

    def _carrot(
        self, q: np.ndarray, xs: list[float], rot: np.ndarray, goal: _Goal, rot_err: float
    ) -> tuple[tuple[float, float, float], float, bool]:
        """``(carrot, TCP step, in transit)`` from the TCP at ``xs``."""
        g, a = goal.g, goal.a
        dx, dy, dz = xs[0] - g[0], xs[1] - g[1], xs[2] - g[2]
        axial = dx * a[0] + dy * a[1] + dz * a[2]  # > 0 below the grasp point
        lat2 = max(0.0, dx * dx + dy * dy + dz * dz - axial * axial)
        above = -axial  # TCP height above the grasp point along the axis
        tol = goal.tol_entry if above >= goal.top + self._drop else goal.tol_deep
        if rot_err <= ROTATION_TOL and lat2 <= tol * tol:
            # along the axis: the carrot is the axis point one step nearer the grasp, so the
            # lateral error is taken out first and the descent runs down the gripper axis
            step = self.approach_step if above <= goal.standoff + 0.005 else self.tcp_step
            h = above - step if above > step else 0.0
            return (g[0] - h * a[0], g[1] - h * a[1], g[2] - h * a[2]), step, False
        frames = self._frames(q, rot)
        p = goal.p
        if self._clear(xs, p, frames):
            return p, self.tcp_step, True
        zt = max(p[2], self._pass_height(xs, p, frames))
        over = (p[0], p[1], zt)
        if xs[2] >= zt or self._clear(xs, over, frames):
            return over, self.tcp_step, True
        return (xs[0], xs[1], zt), self.tcp_step, True

    # ---- clearance -----------------------------------------------------------------------
    def _frames(self, q: np.ndarray, rot: np.ndarray) -> list[tuple[float, ...]]:
        """Each layer in the world's xy plane: ``(bottom offset, ox, oy, ux, uy, vx, vy, Hx,
        Hy)``: its bottom's height relative to the TCP, its centre's offset from the TCP, its
        axes and its half-extents inflated by the clearance and the hand's tilt."""
        (r00, r01, r02), (r10, r11, r12), _ = rot.tolist()
        tilt = math.sqrt(r02 * r02 + r12 * r12)  # sin of the approach axis' angle to vertical
        if self._turns:
            turn = -float(q[-1])
            ct, st = math.cos(turn), math.sin(turn)
        out = []
        m = self.clearance
        for lo, hi, cx, cy, hx, hy, turns in self._layers:
            if turns:
                e1x, e1y, e2x, e2y = ct, st, -st, ct
            else:
                e1x, e1y, e2x, e2y = 1.0, 0.0, 0.0, 1.0
            ux, uy = r00 * e1x + r01 * e1y, r10 * e1x + r11 * e1y
            vx, vy = r00 * e2x + r01 * e2y, r10 * e2x + r11 * e2y
            ox, oy = cx * ux + cy * vx, cx * uy + cy * vy
            grow = m + max(abs(hi), abs(lo)) * tilt
            bottom = lo - max(hx, hy) * tilt - m
            out.append((bottom, ox, oy, ux, uy, vx, vy, hx + grow, hy + grow))
        return out

    def _clear(
        self, a: Sequence[float], b: Sequence[float], frames: list[tuple[float, ...]]
    ) -> bool:
        """True when the TCP segment ``a -> b`` keeps every layer clear of every object."""
        az, bz = a[2], b[2]
        low = az if az < bz else bz
        mx, my = b[0] - a[0], b[1] - a[1]
        for cx, cy, radius, top in self._objects:
            for bottom, ox, oy, ux, uy, vx, vy, hx, hy in frames:
                need = top - bottom  # the TCP height at which this layer clears the top
                if low >= need:
                    continue
                px, py = cx - a[0] - ox, cy - a[1] - oy
                span = _overlap(px, py, mx, my, ux, uy, vx, vy, hx + radius, hy + radius)
                if span is None:
                    continue
                s0, s1 = span
                if az + s0 * (bz - az) < need or az + s1 * (bz - az) < need:
                    return False
        return True

    def _pass_height(
        self, a: Sequence[float], b: Sequence[float], frames: list[tuple[float, ...]]
    ) -> float:
        """The lowest TCP height at which the hand passes from above ``a`` to above ``b``
        clear of every object (``-inf`` when nothing lies between)."""
        mx, my = b[0] - a[0], b[1] - a[1]
        height = -math.inf
        for cx, cy, radius, top in self._objects:
            for bottom, ox, oy, ux, uy, vx, vy, hx, hy in frames:
                need = top - bottom
                if need <= height:
                    continue
                px, py = cx - a[0] - ox, cy - a[1] - oy
                if _overlap(px, py, mx, my, ux, uy, vx, vy, hx + radius, hy + radius):
                    height = need
        return height

    def __repr__(self) -> str:
        return (
            f"GraspApproachPolicy(max_step={self.max_step}, tcp_step={self.tcp_step},"
            f" approach_step={self.approach_step}, clearance={self.clearance})"
        )


def _overlap(
    px: float,
    py: float,
    mx: float,
    my: float,
    ux: float,
    uy: float,
    vx: float,
    vy: float,
    hu: float,
    hv: float,
) -> tuple[float, float] | None:
    """The interval of ``s`` in [0, 1] over which a box (axes ``u``, ``v``, half-extents
    ``hu``, ``hv``) moved by ``s m`` covers the point ``p`` (relative to its start), or
    ``None``: ``|p.u - s m.u| <= hu`` and ``|p.v - s m.v| <= hv`` (two slabs)."""
    s0, s1 = 0.0, 1.0
    pu, mu = px * ux + py * uy, mx * ux + my * uy
    if -1e-12 < mu < 1e-12:
        if abs(pu) > hu:
            return None
    else:
        t0, t1 = (pu - hu) / mu, (pu + hu) / mu
        s0, s1 = (t0, t1) if t0 < t1 else (t1, t0)
        s0 = 0.0 if s0 < 0.0 else s0
        s1 = 1.0 if s1 > 1.0 else s1
        if s0 > s1:
            return None
    pv, mv = px * vx + py * vy, mx * vx + my * vy
    if -1e-12 < mv < 1e-12:
        return None if abs(pv) > hv else (s0, s1)
    t0, t1 = (pv - hv) / mv, (pv + hv) / mv
    if t0 > t1:
        t0, t1 = t1, t0
    s0 = t0 if t0 > s0 else s0
    s1 = t1 if t1 < s1 else s1
    return None if s0 > s1 else (s0, s1)


def rotation_log(m: Sequence[Sequence[float]]) -> tuple[float, float, float]:
    """``log(M)`` of a rotation matrix (nested sequences) as a rotation vector ``theta k``."""
    tr = m[0][0] + m[1][1] + m[2][2]
    c = max(-1.0, min(1.0, 0.5 * (tr - 1.0)))
    wx, wy, wz = m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]
    s = 0.5 * math.sqrt(wx * wx + wy * wy + wz * wz)  # sin(theta)
    theta = math.atan2(s, c)
    if s > 1e-6:
        f = theta / (2.0 * s)
        return wx * f, wy * f, wz * f
    if c > 0.0:  # theta near 0: log = vee(M - M^T) / 2
        return 0.5 * wx, 0.5 * wy, 0.5 * wz
    # theta near pi: the axis from the diagonal (M = 2 k k^T - I), signs from the largest entry
    kk = [math.sqrt(max(0.0, 0.5 * (m[i][i] + 1.0))) for i in range(3)]
    i = max(range(3), key=lambda j: kk[j])
    axis = [0.0, 0.0, 0.0]
    axis[i] = kk[i]
    for j in range(3):
        if j != i:
            axis[j] = 0.5 * (m[i][j] + m[j][i]) / (2.0 * kk[i])
    return axis[0] * theta, axis[1] * theta, axis[2] * theta

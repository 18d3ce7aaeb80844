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
   where the fingers straddle the object and the policy stops. Below the pre-grasp point the
   corridor widens to the slot plane: a hand the user brought down beside the object, with
   the object between the open fingers (off the axis along the fingers' width, not across
   the slot), slides along that plane to the axis, clear of the other objects; one held with
   its fingertips above the object's top moves over to the axis at that height. The TCP's
   step is capped at ``tcp_speed`` throughout, so a lateral error is taken out at that speed
   while the descent proceeds at ``approach_speed``;
2. else ``c = p``, the pre-grasp point ``g - standoff a`` (fingertips above the object's top),
   if the straight TCP segment ``x -> p`` keeps the hand clear of every object;
3. else ``c = (p_x, p_y, z_t)``, above the pre-grasp point at the height ``z_t`` at which the
   hand passes over everything between, if the segment there is clear;
4. else ``c = (x_x, x_y, z_t)``: straight up first. Between 3 and 4 (and wherever a user holds
   a part of the hand within an object's clearance but above its top) the carrot's sideways
   offset shrinks with that part's height over the top, so the motion turns smoothly.

Clearance: the hand (fingers, hand, wrist links: the parts that collide) is a stack of layers,
each a box in the TCP frame between heights ``lo`` and ``hi`` above the TCP; a layer on the link
before the last joint turns by ``-q_7`` about the TCP axis. Each object is an upright cylinder
(its goal's envelope). A TCP segment ``A -> B`` (orientation held) is clear of object ``j`` when,
for every layer, over the part of the segment where the layer's box, inflated by the object's
radius plus ``clearance`` (corners rounded by an octagon), covers the object's axis (an
interval of the segment found by slabs), the layer's bottom stays ``clearance`` above the
object's top. The model assumes an approach axis near vertical (top-down grasps); a tilted
hand inflates every layer by its tilt.

Pure numpy: the arm comes in as an :class:`ArmModel` (a ``pose_jacobian`` callable and plain
numbers), so this module imports no kinematics library. The tick runs compiled
(:mod:`app.blending.policy_grasp_core`, the same operations in the same order: the same ``P``
bit for bit); ``compiled=False`` runs the reference methods below, in Python.
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
from .policy_grasp_core import grasp_step

__all__ = ["ArmModel", "GraspApproachPolicy", "HandLayer", "reach_below", "rotation_log"]

ROTATION_TOL = 0.1
"""rad: the gripper must be this close to the grasp rotation to start the approach."""
ROTATION_SPEED = 1.0
"""rad/s: how fast the gripper turns toward the grasp rotation."""
POSTURE_GAIN = 1.0
"""1/s: the null-space pull toward the goal's grasp configuration while in transit."""
SLOT_REACH = 0.02
"""m: below the pre-grasp point, with the object inside the open slot, the hand slides along
the slot plane to the axis from up to the object's radius plus this off it."""
ALIGN_MARGIN, ALIGN_REACH = 0.002, 0.05
"""m: below the pre-grasp point, with the fingertips at least ``ALIGN_MARGIN`` above the
object's top and the TCP within the object's radius plus ``ALIGN_REACH`` of the axis, the hand
moves over to the axis at that height instead of retreating to the pre-grasp point."""
HOLD_WIDEN = 0.003
"""m: once approaching a goal (corridor, slot plane or aligning over it), the policy keeps
approaching until the hand is this much farther off than the thresholds that let it start
(hysteresis: a hand held at a threshold does not flip between approaching and retreating)."""
TOL_MIN = 0.002
SLOT_MARGIN_ENTRY, SLOT_MARGIN_DEEP = 0.004, 0.002
"""m: the approach corridor's radius is the open fingers' slack around the object (the slot's
half-width less the object's half-width across it) less this margin: the larger one while
the fingertips are above the object's top, the smaller once they straddle it (so a hand held
near the edge does not flip between descending and retreating); at least ``TOL_MIN``."""


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
        return reach_below(self.layers)


def reach_below(layers: Sequence[HandLayer]) -> float:
    """How far the lowest of the hand's ``layers`` (the fingertips) reaches below the TCP (m,
    >= 0)."""
    return max(0.0, -min((layer.lo for layer in layers), default=0.0))


_SQRT_HALF = math.sqrt(0.5)
_Frame = tuple[float, float, float, float, tuple[tuple[float, float, float], ...]]
"""A hand layer in the world's xy plane (see ``GraspApproachPolicy._frames``)."""
_Spans = dict[tuple[int, int], tuple[float, float] | None]
"""Overlap spans of one sweep per (object, layer) (see ``GraspApproachPolicy._freedom``)."""


class _Goal(NamedTuple):
    g: tuple[float, float, float]  # grasp point
    p: tuple[float, float, float]  # pre-grasp point
    a: tuple[float, float, float]  # approach axis (TCP z at the grasp)
    x: tuple[float, float, float]  # along the fingers' width (TCP x at the grasp)
    y: tuple[float, float, float]  # the fingers' closing direction (TCP y at the grasp)
    rotation: np.ndarray  # R_g
    standoff: float
    top: float  # object's top above the grasp point
    tol_entry: float  # corridor radius with the fingers above the object
    tol_deep: float  # ... once they straddle it
    slot_reach: float  # how far along x the slot plane counts as the approach (m)
    near: float  # how far off the axis the hand may align over the object (m)
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
        compiled: run the tick compiled (the same numbers; ``False``: the reference methods,
            in Python).
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
        compiled: bool = True,
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
        # per layer: lo, its reach up or down (for tilt), centre, half-extents, their diagonal
        # support and largest value, and whether it turns with the last joint
        self._layers = tuple(
            (
                float(layer.lo),
                max(abs(float(layer.hi)), abs(float(layer.lo))),
                float(layer.center[0]),
                float(layer.center[1]),
                float(layer.half[0]),
                float(layer.half[1]),
                (float(layer.half[0]) + float(layer.half[1])) * _SQRT_HALF,
                max(float(layer.half[0]), float(layer.half[1])),
                bool(layer.turns),
            )
            for layer in arm.layers
        )
        self._turns = any(layer.turns for layer in arm.layers)
        self._lam2 = self.damping**2 * np.eye(6)
        self._lower = arm.lower
        self._upper = arm.upper
        self._goals: tuple[_Goal, ...] = ()
        self._approaching: set[int] = set()  # goals it is approaching (hysteresis)
        self._objects: tuple[tuple[float, float, float, float], ...] = ()
        self.compiled = bool(compiled)
        self._layer_rows = np.array([(*row[:8], float(row[8])) for row in self._layers])
        limits = self._lower is not None and self._upper is not None
        self._limits = (
            (np.asarray(self._lower, dtype=np.float64), np.asarray(self._upper, dtype=np.float64))
            if limits
            else (np.empty(0), np.empty(0))
        )
        self._packed: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...] = ()
        self._stacked: tuple[np.ndarray, ...] | None = None
        self._kernel_goals: tuple[np.ndarray, ...] | None = None
        self._object_rows = np.empty((0, 4))
        self._numbers = self._params()

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
            radius, top, half_width = goals.envelopes[k].tolist()
            slack = self._slot - half_width
            out.append(
                _Goal(
                    g=tuple(goals.positions[k].tolist()),
                    p=tuple(pregrasp[k].tolist()),
                    a=tuple(rotations[k][:, 2].tolist()),
                    x=tuple(rotations[k][:, 0].tolist()),
                    y=tuple(rotations[k][:, 1].tolist()),
                    rotation=rotations[k].copy(),
                    standoff=float(goals.standoffs[k]),
                    top=top,
                    tol_entry=max(TOL_MIN, slack - SLOT_MARGIN_ENTRY),
                    tol_deep=max(TOL_MIN, slack - SLOT_MARGIN_DEEP),
                    slot_reach=radius + SLOT_REACH,
                    near=radius + ALIGN_REACH,
                    posture=None
                    if goals.configurations is None
                    else goals.configurations[k].copy(),
                )
            )
        if len(out) != len(self._goals):
            self._approaching.clear()
        self._goals = tuple(out)
        self._objects = tuple(
            (float(pos[0]), float(pos[1]), float(env[0]), float(pos[2] + env[1]))
            for pos, env in zip(goals.positions, goals.envelopes, strict=True)
        )
        self._object_rows = np.array(self._objects, dtype=np.float64).reshape(-1, 4)
        self._packed = tuple(_packed(goal) for goal in self._goals)
        self._stacked = _stacked(self._packed, self._approaching)
        self._kernel_goals = None if self._stacked is None else (*self._stacked, self._object_rows)

    def _params(self) -> np.ndarray:
        """The compiled tick's numbers (``policy_grasp_core``'s ``params``), fixed when built."""
        return np.array(
            (
                self._drop,
                self.clearance,
                self.tcp_step,
                self.approach_step,
                self.rotation_step,
                self.posture_step,
                self.max_step,
                float(self._turns),
                float(self._lower is not None and self._upper is not None),
            )
        )

    # ---- the step ------------------------------------------------------------------------
    def step(self, q: np.ndarray, target: Any) -> np.ndarray:
        """``P``, the next configuration from ``Q`` toward goal ``target`` (an index)."""
        if not self._goals:
            raise InvalidInputError("set_goals(goals) must be called before step(Q, goal)")
        if not self.compiled:
            return self._reference_step(q, target)
        k = int(target)
        if type(q) is not np.ndarray or q.dtype != _F64:
            q = np.asarray(q, dtype=np.float64)
        x, rot, jac = self._pose_jacobian(q)
        p, transit, info = grasp_step(
            q, _contiguous(x), _contiguous(rot), _contiguous(jac), *self.kernel_inputs(k)
        )
        if info != 0:  # pragma: no cover - J J^T + lambda^2 I is positive definite
            raise InvalidInputError("arm.pose_jacobian: returned a Jacobian that is not finite")
        self.note_transit(k, transit)
        return p

    def kernel_inputs(self, k: int) -> tuple[Any, ...]:
        """What a fused compiled step hands :func:`~app.blending.policy_grasp_core.grasp_step`
        for goal ``k`` besides ``Q`` and the kinematics pass (its arguments from ``goal`` on);
        then :meth:`note_transit` with the ``transit`` it returned."""
        if not self._goals:
            raise InvalidInputError("set_goals(goals) must be called before step(Q, goal)")
        row, goal_rot, posture = self._packed[k]
        return (
            row,
            goal_rot,
            posture,
            k,
            k in self._approaching,
            self._object_rows,
            self._layer_rows,
            self._numbers,
            self._lam2,
            *self._limits,
        )

    def kernel_goals(self) -> tuple[np.ndarray, ...] | None:
        """:meth:`kernel_inputs`' goal-set part for every goal at once, for a fused step that
        picks G* itself: ``(rows (n, 21), grasp rotations (n, 3, 3), postures (n, dof) or
        (n, 0), approaching (n,) bools, objects (n, 4))``; ``None`` when the goals' postures
        cannot be stacked. The same objects until the goals change (``approaching`` kept by
        :meth:`note_transit`); the rest of ``kernel_inputs`` is :meth:`kernel_constants`."""
        if not self._goals:
            raise InvalidInputError("set_goals(goals) must be called before step(Q, goal)")
        return self._kernel_goals

    def kernel_constants(self) -> tuple[np.ndarray, ...]:
        """:meth:`kernel_inputs`' last five, fixed when built: ``(layers, params, lambda^2 I,
        lower, upper)``."""
        return (self._layer_rows, self._numbers, self._lam2, *self._limits)

    def note_transit(self, k: int, transit: bool) -> None:
        """After a step toward goal ``k``: its hysteresis, as :meth:`step` keeps it."""
        if transit:
            self._approaching.discard(k)
        else:
            self._approaching.add(k)
        if self._stacked is not None:
            self._stacked[3][k] = not transit

    def _reference_step(self, q: np.ndarray, target: Any) -> np.ndarray:
        """``step`` in Python: the reference the compiled tick is tested equal to."""
        goal = self._goals[int(target)]
        x, rot, jac = self._pose_jacobian(q)
        xs = x.tolist()
        e = rotation_log(goal.rotation.dot(rot.T).tolist())
        rot_err = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        k = int(target)
        carrot, speed, transit = self._carrot(q, xs, rot, k, rot_err)
        self.note_transit(k, transit)
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
            twist -= jac.dot(z)
        a = jac.dot(jac.T)  # ndarray.dot: less call overhead than @ on these small arrays
        a += self._lam2
        _, y, info = dposv(a, twist, overwrite_a=1, overwrite_b=1)
        if info != 0:  # pragma: no cover - J J^T + lambda^2 I is positive definite
            raise InvalidInputError("arm.pose_jacobian: returned a Jacobian that is not finite")
        dq = jac.T.dot(y)
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
        self, q: np.ndarray, xs: list[float], rot: np.ndarray, k: int, rot_err: float
    ) -> tuple[tuple[float, float, float], float, bool]:
        """``(carrot, TCP step, in transit)`` from the TCP at ``xs`` toward goal ``k``."""
        goal = self._goals[k]
        g, a, gx, gy = goal.g, goal.a, goal.x, goal.y
        dx, dy, dz = xs[0] - g[0], xs[1] - g[1], xs[2] - g[2]
        above = -(dx * a[0] + dy * a[1] + dz * a[2])  # TCP height over the grasp point
        ex = dx * gx[0] + dy * gx[1] + dz * gx[2]  # off the axis along the fingers' width
        ey = dx * gy[0] + dy * gy[1] + dz * gy[2]  # ... across the slot
        frames = None
        held = k in self._approaching
        widen = HOLD_WIDEN if held else 0.0
        if rot_err <= ROTATION_TOL + (0.05 if held else 0.0):
            tol = (goal.tol_entry if above >= goal.top + self._drop else goal.tol_deep) + widen
            # the axis point one step down (at approach_speed below the pre-grasp point):
            # with the TCP's step capped at tcp_speed, the lateral error is taken out first,
            # then the descent runs down the gripper axis
            sink = self.approach_step if above <= goal.standoff + 0.005 else self.tcp_step
            h = above - sink if above > sink else 0.0
            down = (g[0] - h * a[0], g[1] - h * a[1], g[2] - h * a[2])
            if ex * ex + ey * ey <= tol * tol:
                return down, self.tcp_step, False
            if above < goal.standoff:  # below the pre-grasp point (a user brought it there)
                frames = self._frames(q, rot)
                # the object in the open slot: the fingers slide along the slot plane to the
                # axis (and on down), the hand clear of the other objects
                if abs(ey) + abs(ex) * rot_err <= tol and abs(ex) <= goal.slot_reach:
                    spans: _Spans = {}  # toward down's xy: shared by the three tests
                    if self._freedom(xs, down, frames, skip=k, spans=spans) >= 1.0:
                        return down, self.tcp_step, False
                    # another object's clearance floor is in the way: slide at that height
                    floor = self._pass_height(xs, down, frames, skip=k, spans=spans)
                    slide = (down[0], down[1], max(down[2], floor))
                    f = self._freedom(xs, slide, frames, skip=k, spans=spans)
                    if f > 0.0:
                        return _toward(xs, slide, f), self.tcp_step, False
                # the fingertips above the object's top, near it: over to the axis at this
                # height, then down
                if (
                    above - self._drop >= goal.top + (0.0 if held else ALIGN_MARGIN)
                    and ex * ex + ey * ey <= goal.near * goal.near
                ):
                    level = (g[0] - above * a[0], g[1] - above * a[1], g[2] - above * a[2])
                    f = self._freedom(xs, level, frames, skip=k)
                    if f > 0.0:
                        return _toward(xs, level, f), self.tcp_step, False
        if frames is None:
            frames = self._frames(q, rot)
        p = goal.p
        spans: _Spans = {}  # toward p's xy: shared by the three tests
        f = self._freedom(xs, p, frames, spans=spans)
        if f > 0.0:
            return _toward(xs, p, f), self.tcp_step, True
        zt = max(p[2], self._pass_height(xs, p, frames, spans=spans))
        over = (p[0], p[1], zt)
        f = 1.0 if xs[2] >= zt else self._freedom(xs, over, frames, spans=spans)
        return _toward(xs, over, f), self.tcp_step, True

    # ---- clearance -----------------------------------------------------------------------
    def _frames(self, q: np.ndarray, rot: np.ndarray) -> list[_Frame]:
        """Each layer in the world's xy plane: its bottom's height relative to the TCP (less
        the clearance), its centre's offset from the TCP, how much to inflate it (clearance
        and tilt) and its support in four directions (its axes and their diagonals)."""
        (r00, r01, r02), (r10, r11, r12), _ = rot.tolist()
        tilt = math.sqrt(r02 * r02 + r12 * r12)  # sin of the approach axis' angle to vertical
        if self._turns:
            turn = -float(q[-1])
            ct, st = math.cos(turn), math.sin(turn)
        out = []
        m = self.clearance
        for lo, reach, cx, cy, hx, hy, hd, hmax, turns in self._layers:
            if turns:
                ux, uy = r00 * ct + r01 * st, r10 * ct + r11 * st
                vx, vy = r01 * ct - r00 * st, r11 * ct - r10 * st
            else:
                ux, uy, vx, vy = r00, r10, r01, r11
            dirs = (
                (ux, uy, hx),
                (vx, vy, hy),
                ((ux + vx) * _SQRT_HALF, (uy + vy) * _SQRT_HALF, hd),
                ((ux - vx) * _SQRT_HALF, (uy - vy) * _SQRT_HALF, hd),
            )
            out.append(
                (
                    lo - hmax * tilt - m,  # bottom, less the clearance
                    cx * ux + cy * vx,  # centre's offset from the TCP
                    cx * uy + cy * vy,
                    m + reach * tilt,  # inflation
                    dirs,
                )
            )
        return out

    def _freedom(
        self,
        a: Sequence[float],
        b: Sequence[float],
        frames: list[_Frame],
        *,
        skip: int = -1,
        spans: _Spans | None = None,
    ) -> float:
        """How much of the TCP segment ``a -> b`` the hand may take, clear of every object
        but ``skip``: 1 all of it, 0 none. ``spans``: the sweep's overlaps already worked out
        (and filled in), shared by the tests of segments from ``a`` to the same ``xy``.

        A layer already within an object's clearance zone at ``a`` (a user may hold the hand
        there) does not block a segment that takes it away from the object: beside the object,
        a segment along which the layer's distance to it grows; above its top, a segment that
        does not descend, whose sideways share then falls with the layer's height above the
        top, ``f = (z - z_top) / clearance``, to 0 (straight up) at the top, so the motion
        changes smoothly there.
        """
        az, bz = a[2], b[2]
        low = az if az < bz else bz
        rising = bz >= az
        m = self.clearance
        mx, my = b[0] - a[0], b[1] - a[1]
        free = 1.0
        for j, (cx, cy, radius, top) in enumerate(self._objects):
            if j == skip:
                continue
            for i, (bottom, ox, oy, grow, dirs) in enumerate(frames):
                need = top - bottom  # the TCP height at which this layer clears the top
                if low >= need:
                    continue
                span = _swept(
                    spans, j, i, cx - a[0] - ox, cy - a[1] - oy, mx, my, dirs, radius + grow
                )
                if span is None:
                    continue
                s0, s1 = span
                if az + s0 * (bz - az) >= need and az + s1 * (bz - az) >= need:
                    continue
                if s0 > 0.0:  # the segment would enter this object's clearance zone
                    return 0.0
                # already within it (a user may hold the hand there): a layer beside the
                # object may move away from it, one above it may rise, easing sideways
                (ux, uy, hu), (vx, vy, hv) = dirs[0], dirs[1]
                px, py = cx - a[0] - ox, cy - a[1] - oy
                du, dv = px * ux + py * uy, px * vx + py * vy
                du -= hu if du > hu else (-hu if du < -hu else du)
                dv -= hv if dv > hv else (-hv if dv < -hv else dv)
                if du * du + dv * dv > radius * radius and (
                    (mx * ux + my * uy) * du + (mx * vx + my * vy) * dv <= 0.0
                ):
                    continue
                if rising and az > need - m:
                    free = min(free, (az - need + m) / m)
                    continue
                return 0.0
        return free

    def _pass_height(
        self,
        a: Sequence[float],
        b: Sequence[float],
        frames: list[_Frame],
        *,
        skip: int = -1,
        spans: _Spans | None = None,
    ) -> float:
        """The lowest TCP height at which the hand passes from above ``a`` to above ``b``
        clear of every object but ``skip`` (``-inf`` when nothing lies between); ``spans`` as
        in ``_freedom``."""
        mx, my = b[0] - a[0], b[1] - a[1]
        height = -math.inf
        for j, (cx, cy, radius, top) in enumerate(self._objects):
            if j == skip:
                continue
            for i, (bottom, ox, oy, grow, dirs) in enumerate(frames):
                need = top - bottom
                if need <= height:
                    continue
                if _swept(spans, j, i, cx - a[0] - ox, cy - a[1] - oy, mx, my, dirs, radius + grow):
                    height = need
        return height

    def __repr__(self) -> str:
        return (
            f"GraspApproachPolicy(max_step={self.max_step}, tcp_step={self.tcp_step},"
            f" approach_step={self.approach_step}, clearance={self.clearance})"
        )


_F64 = np.dtype(np.float64)


def _contiguous(a: Any) -> np.ndarray:
    """``a`` as a C-contiguous float array (itself when it is one)."""
    if type(a) is np.ndarray and a.dtype == _F64 and a.flags.c_contiguous:
        return a
    return np.ascontiguousarray(a, dtype=np.float64)


def _packed(goal: _Goal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A goal as the compiled tick takes it: its row (``policy_grasp_core``'s ``goal``), its
    grasp rotation and its posture (empty when it has none)."""
    row = np.array(
        (
            *goal.g,
            *goal.p,
            *goal.a,
            *goal.x,
            *goal.y,
            goal.standoff,
            goal.top,
            goal.tol_entry,
            goal.tol_deep,
            goal.slot_reach,
            goal.near,
        ),
        dtype=np.float64,
    )
    posture = np.empty(0) if goal.posture is None else np.ascontiguousarray(goal.posture, float)
    return row, np.ascontiguousarray(goal.rotation, dtype=np.float64), posture


def _stacked(
    packed: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...], approaching: set[int]
) -> tuple[np.ndarray, ...] | None:
    """The goals' packed rows, rotations and postures stacked, and which are approached;
    ``None`` when some goals have a posture and others not."""
    if not packed or len({posture.shape for _, _, posture in packed}) > 1:
        return None
    flags = np.zeros(len(packed), dtype=np.bool_)
    flags[sorted(k for k in approaching if k < len(packed))] = True
    return (
        np.stack([row for row, _, _ in packed]),
        np.stack([rot for _, rot, _ in packed]),
        np.stack([posture for _, _, posture in packed]),
        flags,
    )


def _toward(x: Sequence[float], c: Sequence[float], f: float) -> tuple[float, float, float]:
    """The carrot ``c`` with only the share ``f`` of its horizontal offset from ``x``."""
    if f >= 1.0:
        return c[0], c[1], c[2]
    return x[0] + f * (c[0] - x[0]), x[1] + f * (c[1] - x[1]), c[2]


def _swept(
    spans: _Spans | None,
    j: int,
    i: int,
    px: float,
    py: float,
    mx: float,
    my: float,
    dirs: tuple[tuple[float, float, float], ...],
    rho: float,
) -> tuple[float, float] | None:
    """``_overlap`` of layer ``i`` and object ``j``, from ``spans`` when already worked out
    there for this sweep (the same ``a`` and the same horizontal motion ``m``)."""
    if spans is None:
        return _overlap(px, py, mx, my, dirs, rho)
    key = (j, i)
    if key in spans:
        return spans[key]
    span = spans[key] = _overlap(px, py, mx, my, dirs, rho)
    return span


def _overlap(
    px: float,
    py: float,
    mx: float,
    my: float,
    dirs: tuple[tuple[float, float, float], ...],
    rho: float,
) -> tuple[float, float] | None:
    """The interval of ``s`` in [0, 1] over which a box moved by ``s m``, inflated by ``rho``,
    covers the point ``p`` (relative to the box's centre at ``s = 0``), or ``None``.

    The box's support ``h_i`` in each direction ``n_i`` of ``dirs`` (its two axes and their
    diagonals) makes slabs ``|p.n_i - s m.n_i| <= h_i + rho``, whose intersection is the box
    with octagonal corners: within 8 % of ``rho`` of the box rounded by ``rho``, never inside
    it.
    """
    s0, s1 = 0.0, 1.0
    for nx, ny, h in dirs:
        pn, mn = px * nx + py * ny, mx * nx + my * ny
        h += rho
        if -1e-12 < mn < 1e-12:
            if pn > h or pn < -h:
                return None
            continue
        t0, t1 = (pn - h) / mn, (pn + h) / mn
        if t0 > t1:
            t0, t1 = t1, t0
        if t0 > s0:
            s0 = t0
        if t1 < s1:
            s1 = t1
        if s0 > s1:
            return None
    return s0, s1


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

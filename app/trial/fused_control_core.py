"""The trial's control step compiled in one call: kinematics pass, ``U``, ``P`` and the blend.

From ``Q``, the steered target and the user's input ``x`` (prediction, confidence and
arbitration read neither ``U`` nor ``P``, so they come first):

    P(G | xi), G*, conf, alpha                (app.blending.assess_core, the stock components;
                                               or worked out by the caller and given)
    x, R, J = phi(Q)                          (app.robot.kinematics_core)
    U = IK step toward the target             (app.teleop.ik_step_core, w = log(R* R^T))
    P = grasp policy step toward G*           (app.blending.policy_grasp_core)
    command = (1 - alpha) U + alpha P

each step's maths the very functions its component's compiled path runs (the twist, then the
caps and limits); what differs is the arithmetic's library: the kinematics pass composed here
rather than by pinocchio's ``computeFrameJacobian``, the IK's ``log`` the policy's rather than
pinocchio's ``log3``, and the damped least squares, the products and ``|dq|`` in plain loops
(``app.compiled.dls_loops``) rather than by BLAS and LAPACK (code that MuJoCo's step evicts
from the caches each tick). So ``U``, ``P`` and the command equal the components' to a few
ulps, not bit for bit (``tests/test_fused_control.py``).
"""

from __future__ import annotations

import numpy as np

from app.blending.assess_core import AMNESIC, GIVEN, assess
from app.blending.blend import MAX_ABS_INPUT
from app.blending.policy_grasp_core import grasp_finish, grasp_twist, rotation_log
from app.compiled import dls_loops, jit
from app.robot.kinematics_core import tcp_pose_jacobian
from app.teleop.ik_step_core import ik_finish, ik_twist

__all__ = ["control_step", "pack_arm", "pack_goals", "warm_up"]


@jit
def control_step(
    q: np.ndarray,
    target: np.ndarray,
    x: np.ndarray,
    robot_x: np.ndarray,
    direction: np.ndarray,
    points: np.ndarray,
    pred_points: np.ndarray,
    pred_vec: np.ndarray,
    pred_vec2: np.ndarray,
    prev: np.ndarray,
    nums: np.ndarray,
    k: int,
    s1: float,
    s2: float,
    ik_limit: float,
    arm: np.ndarray,
    goal_set: np.ndarray,
    approaching: np.ndarray,
    out: np.ndarray,
) -> tuple[int, bool, int, bool, float, float, float, float, float]:
    """``[U; P; command; P(G | xi)]`` into ``out`` ``(3 dof + n,)`` (a fresh array from the
    caller: cheaper than returning a new one), and ``(G*, whether G*'s hysteresis flips (in
    transit while ``approaching``, or the other way: ``GraspApproachPolicy.note_transit`` with
    ``not approaching[G*]``), LAPACK info of P's solve, whether Q, U and P are finite and below
    the blender's MAX_ABS_INPUT, conf, d, motion agreement, alpha, C(xi_{S->U}))``.

    The arguments from ``x`` to ``s2`` are :func:`~app.blending.assess_core.assess`'s
    (``s1``, ``s2``: its ``c_su`` and ``b``), or, with ``nums[0] == GIVEN``, ``G*`` given as
    ``k`` and ``alpha`` as ``s1`` (prediction, confidence and arbitration worked out by the
    caller; ``P(G | xi)`` then left unset); ``ik_limit`` the IK's speed limit; ``arm`` the
    arm's fixed arrays in one (:func:`pack_arm`); then ``grasp_step``'s goal-set inputs in one
    (:func:`pack_goals`: each goal's row of ``goals``, ``goal_rots`` and ``postures`` --
    ``(n, 0)``: none -- and the objects) and each goal's hysteresis in ``approaching``."""
    dof = q.shape[0]
    if nums[0] == GIVEN:
        c = d = motion = c_su = 0.0
        alpha = s1
    else:
        probs = out[3 * dof :]
        k, c, d, motion, alpha, c_su = assess(
            x, robot_x, direction, points, pred_points, pred_vec, pred_vec2, prev, nums, k, s1,
            s2, probs,
        )  # fmt: skip
        if k < 0:
            return k, False, 0, False, c, d, motion, alpha, c_su  # nothing noted
    held = approaching[k]
    goal_rot = _two(goal_set, 1)[k].reshape((3, 3))
    transit, info, finite = _control(
        q, target, alpha, _two(arm, 0), _one(arm, 1), _two(arm, 2), _one(arm, 3), _two(arm, 4),
        _one(arm, 5), _one(arm, 6), _one(arm, 7), ik_limit, _two(goal_set, 0)[k], goal_rot,
        _two(goal_set, 2)[k], k, held, _two(goal_set, 3), _two(arm, 8), _one(arm, 9),
        _two(arm, 10), _one(arm, 11), _one(arm, 12), out,
    )  # fmt: skip
    return k, transit == held, info, finite, c, d, motion, alpha, c_su


_ARM_PARTS = 13
"""The arm's fixed arrays (:func:`pack_arm`): the chain, the TCP, then the IK's ``R*``,
posture, ``l^2 I``, lower, upper and params, then the policy's layers, params, ``l^2 I``,
lower and upper."""


def pack_arm(parts: tuple[np.ndarray, ...]) -> np.ndarray:
    """The arm's fixed arrays (``_ARM_PARTS``, in that order) in one float array, so a tick
    hands the kernel one argument for them: a header of ``(offset, rows, columns)`` per
    array (columns ``-1`` for a vector), then their numbers."""
    if len(parts) != _ARM_PARTS:
        raise ValueError(f"pack_arm: expected {_ARM_PARTS} arrays, got {len(parts)}")
    return _pack(parts)


def pack_goals(
    goals: np.ndarray, goal_rots: np.ndarray, postures: np.ndarray, objects: np.ndarray
) -> np.ndarray:
    """The grasp policy's goal-set arrays (``GraspApproachPolicy.kernel_goals`` but the
    hysteresis) in one float array as :func:`pack_arm` packs the arm's: the rows ``(n, 21)``,
    the grasp rotations as ``(n, 9)``, the postures ``(n, dof)`` or ``(n, 0)``, the objects
    ``(n, 4)``."""
    n = goals.shape[0]
    return _pack((goals, goal_rots.reshape(n, 9), postures.reshape(n, -1), objects))


def _pack(parts: tuple[np.ndarray, ...]) -> np.ndarray:
    """``parts`` (vectors and matrices) in one float array: a header of ``(offset, rows,
    columns)`` per array (columns ``-1`` for a vector), then their numbers."""
    header: list[float] = []
    offset = 3 * len(parts)
    for a in parts:
        rows, cols = (a.shape[0], -1) if a.ndim == 1 else a.shape
        header += [offset, rows, cols]
        offset += a.size
    return np.concatenate([np.array(header, dtype=np.float64), *(a.ravel() for a in parts)])


@jit
def _one(arm: np.ndarray, i: int) -> np.ndarray:
    """Vector ``i`` of a packed arm."""
    o, n = int(arm[3 * i]), int(arm[3 * i + 1])
    return arm[o : o + n]


@jit
def _two(arm: np.ndarray, i: int) -> np.ndarray:
    """Matrix ``i`` of a packed arm."""
    o, r, c = int(arm[3 * i]), int(arm[3 * i + 1]), int(arm[3 * i + 2])
    return arm[o : o + r * c].reshape((r, c))


@jit
def _control(
    q: np.ndarray,
    target: np.ndarray,
    alpha: float,
    chain: np.ndarray,
    tcp: np.ndarray,
    ik_rot: np.ndarray,
    ik_posture: np.ndarray,
    ik_damp: np.ndarray,
    ik_lower: np.ndarray,
    ik_upper: np.ndarray,
    ik_params: np.ndarray,
    ik_limit: float,
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
    out: np.ndarray,
) -> tuple[bool, int, bool]:
    """``U``, ``P`` and the command into ``out[:3 dof]``; ``(in transit, LAPACK info of P's
    solve, finite)`` as :func:`control_step` gives them."""
    x, rot, jac = tcp_pose_jacobian(q, chain, tcp)
    twist, z, pull = ik_twist(q, target, x, _log_of(ik_rot, rot), ik_posture, ik_params, ik_limit)
    dq, info = dls_loops(jac, twist, z, pull, ik_damp)
    u = q.copy() if info != 0 else ik_finish(q, dq, ik_lower, ik_upper, ik_params)
    e = _log_of(goal_rot, rot)
    twist, z, pull, transit = grasp_twist(
        q, x, rot, (e[0], e[1], e[2]), goal, posture, k, held, objects, layers, params
    )
    dq, info = dls_loops(jac, twist, z, pull, lam2)
    dq2 = 0.0
    for i in range(dq.shape[0]):
        dq2 += dq[i] * dq[i]
    p = grasp_finish(q, dq, dq2, params, lower, upper)
    size = 0.0  # sum of |Q|, |U| and |P|: finite and below MAX_ABS_INPUT, or not (NaN: not)
    dof = q.shape[0]
    keep = 1.0 - alpha
    for i in range(dof):
        size += abs(q[i]) + abs(u[i]) + abs(p[i])
        out[i] = u[i]
        out[dof + i] = p[i]
        cmd = u[i] * keep
        if alpha != 0.0:  # as the blender: alpha = 0 gives U itself
            cmd += alpha * p[i]
        out[2 * dof + i] = cmd
    return transit, info, size < MAX_ABS_INPUT


@jit
def _log_of(a: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``log(A R^T)`` (3,) of two rotations, the product in plain loops."""
    m = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            m[i, j] = a[i, 0] * r[j, 0] + a[i, 1] * r[j, 1] + a[i, 2] * r[j, 2]
    w0, w1, w2 = rotation_log(m)
    return np.array((w0, w1, w2))


def warm_up() -> None:
    """Compile :func:`control_step` (or load it from numba's cache) with a tick's argument
    types, on a dummy arm (two goals, an amnesic prediction)."""
    z = np.zeros
    chain = z((7, 13))
    chain[:, 0] = chain[:, 4] = chain[:, 8] = 1.0
    chain[:, 12] = 2.0
    tcp = np.array([1.0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0])
    ones, eye = np.ones, np.eye
    ik = (eye(3), z(7), eye(6), -ones(7), ones(7), z(7))
    arm = pack_arm((chain, tcp, *ik, z((1, 9)), ones(9), eye(6), -ones(7), ones(7)))
    points = np.array([[0.5, 0.1, 0.1], [0.5, -0.1, 0.1]])
    nums = np.array([AMNESIC, -20.0, 0.0, 4.0, 1.0, 0.5, 0.7, 0.5 / 0.7])
    goal_set = pack_goals(z((2, 21)), np.stack((eye(3), eye(3))), z((2, 7)), z((2, 4)))
    control_step(
        *(z(7), z(3), z(3), z(3), z(0), points, points, z(2), z(2), z(3), nums, 0, 0.0, 1.0),
        *(0.3, arm, goal_set, np.zeros(2, dtype=np.bool_), np.empty(7 * 3 + 2)),
    )

"""The trial's control step compiled in one call: kinematics pass, ``U``, ``P`` and the blend.

From ``Q``, the steered target and ``alpha`` (prediction, confidence and arbitration ran
before, in Python: none of them reads ``U`` or ``P``):

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

from app.blending.blend import MAX_ABS_INPUT
from app.blending.policy_grasp_core import grasp_finish, grasp_twist, rotation_log
from app.compiled import dls_loops, jit
from app.robot.kinematics_core import tcp_pose_jacobian
from app.teleop.ik_step_core import ik_finish, ik_twist

__all__ = ["control_step", "warm_up"]


@jit
def control_step(
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
) -> tuple[np.ndarray, bool, int, bool]:
    """``([U; P; command], in transit, LAPACK info of P's solve, whether Q, U and P are finite
    and below the blender's MAX_ABS_INPUT)``; the arguments after ``tcp``
    are ``ik_step``'s (from ``ik_rot``, the IK's ``R*``) and ``grasp_step``'s (from ``goal``)."""
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
    for i in range(q.shape[0]):
        size += abs(q[i]) + abs(u[i]) + abs(p[i])
    out = np.empty((3, q.shape[0]))  # one array for Python: each one returned costs a box
    out[0] = u
    out[1] = p
    cmd = out[2]
    keep = 1.0 - alpha
    for i in range(cmd.shape[0]):
        cmd[i] = u[i] * keep
        if alpha != 0.0:  # as the blender: alpha = 0 gives U itself
            cmd[i] += alpha * p[i]
    return out, transit, info, size < MAX_ABS_INPUT


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
    types, on a dummy arm."""
    z = np.zeros
    chain = z((7, 13))
    chain[:, 0] = chain[:, 4] = chain[:, 8] = 1.0
    chain[:, 12] = 2.0
    tcp = np.array([1.0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0])
    ones = np.ones
    control_step(
        *(z(7), z(3), 0.5, chain, tcp, np.eye(3), z(7), np.eye(6), -ones(7), ones(7), z(7), 0.3),
        *(z(21), np.eye(3), z(7), 0, False, z((2, 4)), z((1, 9)), ones(9), np.eye(6)),
        *(-ones(7), ones(7)),
    )

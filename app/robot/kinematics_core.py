"""The TCP's pose and Jacobian compiled, for the control tick's fused step.

Pinocchio's model (:class:`~app.robot.kinematics.Kinematics`) is the model of record: this
kernel takes its serial chain as numbers (:meth:`Kinematics.chain`) and composes it the way
its forward kinematics does,

    oM_i = oM_{i-1} M_i Rot_{a_i}(q_i),        oM_tcp = oM_n M_tcp,

(``M_i`` joint ``i``'s placement in its parent, ``a_i`` its axis: x, y or z), then the
world-aligned Jacobian of the TCP (pinocchio's ``LOCAL_WORLD_ALIGNED``), column ``i``

    J_i = [w_i x (p_tcp - p_i); w_i],          w_i = oR_i e_{a_i},  p_i = op_i.

Not the same operations in the same order as pinocchio's (Eigen's products): the same numbers
to a few ulps, tested against pinocchio (``tests/test_fused_control.py``).

``chain`` (n, 13): per joint its placement's rotation (9, row-major), translation (3) and axis
(0, 1, 2 for x, y, z); ``tcp`` (12,): the TCP's placement in the last joint (rotation, then
translation).
"""

from __future__ import annotations

import math

import numpy as np

from app.compiled import jit

__all__ = ["tcp_pose_jacobian", "warm_up"]


@jit
def tcp_pose_jacobian(
    q: np.ndarray, chain: np.ndarray, tcp: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """TCP position (3,), rotation (3, 3) and ``J(q)`` (6, n) of the serial chain at ``q``."""
    n = chain.shape[0]
    r = np.eye(3)
    p = np.zeros(3)
    origins = np.empty((n, 3))
    axes = np.empty((n, 3))
    m = np.empty((3, 3))
    for i in range(n):
        row = chain[i]
        # p <- p + R t_i ; R <- R R_i  (the joint's placement in its parent)
        t0, t1, t2 = row[9], row[10], row[11]
        p0 = p[0] + (r[0, 0] * t0 + r[0, 1] * t1 + r[0, 2] * t2)
        p1 = p[1] + (r[1, 0] * t0 + r[1, 1] * t1 + r[1, 2] * t2)
        p2 = p[2] + (r[2, 0] * t0 + r[2, 1] * t1 + r[2, 2] * t2)
        p[0], p[1], p[2] = p0, p1, p2
        for a in range(3):
            for b in range(3):
                m[a, b] = r[a, 0] * row[b] + r[a, 1] * row[3 + b] + r[a, 2] * row[6 + b]
        # R <- R Rot_axis(q_i): two columns turn, the axis column stays
        c, s = math.cos(q[i]), math.sin(q[i])
        axis = int(row[12])
        j, k = (1, 2) if axis == 0 else ((2, 0) if axis == 1 else (0, 1))
        for a in range(3):
            mj, mk = m[a, j], m[a, k]
            r[a, j] = mj * c + mk * s
            r[a, k] = mk * c - mj * s
            r[a, axis] = m[a, axis]
        origins[i, 0], origins[i, 1], origins[i, 2] = p0, p1, p2
        axes[i, 0], axes[i, 1], axes[i, 2] = r[0, axis], r[1, axis], r[2, axis]
    x = np.empty(3)
    rot = np.empty((3, 3))
    for a in range(3):
        x[a] = p[a] + (r[a, 0] * tcp[9] + r[a, 1] * tcp[10] + r[a, 2] * tcp[11])
        for b in range(3):
            rot[a, b] = r[a, 0] * tcp[b] + r[a, 1] * tcp[3 + b] + r[a, 2] * tcp[6 + b]
    jac = np.empty((6, n))
    for i in range(n):
        w0, w1, w2 = axes[i, 0], axes[i, 1], axes[i, 2]
        d0, d1, d2 = x[0] - origins[i, 0], x[1] - origins[i, 1], x[2] - origins[i, 2]
        jac[0, i] = w1 * d2 - w2 * d1
        jac[1, i] = w2 * d0 - w0 * d2
        jac[2, i] = w0 * d1 - w1 * d0
        jac[3, i], jac[4, i], jac[5, i] = w0, w1, w2
    return x, rot, jac


def warm_up() -> None:
    """Compile :func:`tcp_pose_jacobian` (or load it from numba's cache) on a dummy chain."""
    chain = np.zeros((7, 13))
    chain[:, 0] = chain[:, 4] = chain[:, 8] = 1.0
    chain[:, 12] = 2.0
    tcp_pose_jacobian(np.zeros(7), chain, np.array([1.0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]))

"""The IK step's numbers compiled: twist, damped least squares, joint caps and limits.

The same operations in the same order as :class:`~app.teleop.ik_step.IKStep`'s reference (its
module docstring has the maths), so ``U`` comes out bit for bit the same
(``tests/test_tick_fast_path.py``); the kinematics pass and ``log3`` stay pinocchio's calls.

``params`` (7,): ``dt, gain, rotation_gain, max_angular_speed, posture_gain, max_joint_step,
posture (0/1)``.
"""

from __future__ import annotations

import math

import numpy as np

from app.compiled import dls, jit

__all__ = ["ik_finish", "ik_step", "ik_twist", "warm_up"]


@jit
def ik_step(
    q: np.ndarray,
    target: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    jac: np.ndarray,
    posture: np.ndarray,
    damp: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    params: np.ndarray,
    limit: float,
) -> np.ndarray:
    """``U`` from ``Q`` toward ``target``, with ``x``, ``J`` the pass at ``Q`` and ``w =
    log3(R* R^T)``; ``Q`` unchanged (a copy) when the solve fails."""
    twist, z, pull = ik_twist(q, target, x, w, posture, params, limit)
    dq, info = dls(jac, twist, z, pull, damp)
    if info != 0:
        return q.copy()
    return ik_finish(q, dq, lower, upper, params)


@jit
def ik_twist(
    q: np.ndarray,
    target: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    posture: np.ndarray,
    params: np.ndarray,
    limit: float,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(dt [v; w], posture velocity z times dt, whether there is a posture)``."""
    dt, gain, sw, max_angular_speed = params[0], params[1], params[2], params[3]
    ex, ey, ez = target[0] - x[0], target[1] - x[1], target[2] - x[2]
    en = math.sqrt(ex * ex + ey * ey + ez * ez)
    sv = (gain if gain * en <= limit else limit / en) * dt
    rx, ry, rz = w[0], w[1], w[2]
    rn = math.sqrt(rx * rx + ry * ry + rz * rz)
    if sw * rn > max_angular_speed:
        sw = max_angular_speed / rn
    sw *= dt
    twist = np.array((sv * ex, sv * ey, sv * ez, sw * rx, sw * ry, sw * rz))
    pull = params[6] != 0.0
    z = np.empty(0)
    if pull:
        z = posture - q
        z *= params[4] * dt
    return twist, z, pull


@jit
def ik_finish(
    q: np.ndarray, dq: np.ndarray, lower: np.ndarray, upper: np.ndarray, params: np.ndarray
) -> np.ndarray:
    """``clip(Q + dq)``, ``dq`` first scaled so no joint moves more than ``max_joint_step``
    (``dq`` overwritten: it becomes ``U``)."""
    biggest = 0.0
    for i in range(dq.shape[0]):  # max(map(abs, dq)): the first of the largest
        a = abs(dq[i])
        if i == 0 or a > biggest:
            biggest = a
    if biggest > params[5]:
        dq *= params[5] / biggest
    dq += q
    for i in range(dq.shape[0]):  # np.maximum with the lower limits, then np.minimum
        lo = dq[i] if dq[i] >= lower[i] else lower[i]
        dq[i] = lo if lo <= upper[i] else upper[i]
    return dq


def warm_up() -> None:
    """Compile :func:`ik_step` (or load it from numba's cache) with the argument types of a
    tick, on a dummy arm."""
    z = np.zeros
    ik_step(z(7), z(3), z(3), z(3), z((6, 7)), z(7), np.eye(6), -np.ones(7), np.ones(7), z(7), 0.3)

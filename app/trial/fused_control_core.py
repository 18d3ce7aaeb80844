"""The trial's control step compiled in one call: kinematics pass, ``U``, ``P`` and the blend.

From ``Q``, the steered target and ``alpha`` (prediction, confidence and arbitration ran
before, in Python: none of them reads ``U`` or ``P``):

    x, R, J = phi(Q)                          (app.robot.kinematics_core)
    U = IK step toward the target             (app.teleop.ik_step_core, w = log(R* R^T))
    P = grasp policy step toward G*           (app.blending.policy_grasp_core)
    command = (1 - alpha) U + alpha P

each kernel the very one its component's compiled path runs; only the kinematics pass (and
the IK's ``log``) differ from the components' own (pinocchio's ``computeFrameJacobian`` and
``log3``), by a few ulps (``tests/test_fused_control.py``).
"""

from __future__ import annotations

import numpy as np

from app.blending.policy_grasp_core import grasp_step, rotation_log
from app.compiled import jit
from app.robot.kinematics_core import tcp_pose_jacobian
from app.teleop.ik_step_core import ik_step

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
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool, int]:
    """``(U, P, command, in transit, LAPACK info of P's solve)``; the arguments after ``tcp``
    are ``ik_step``'s (from ``ik_rot``, the IK's ``R*``) and ``grasp_step``'s (from ``goal``)."""
    x, rot, jac = tcp_pose_jacobian(q, chain, tcp)
    w0, w1, w2 = rotation_log(np.dot(ik_rot, rot.T))
    w = np.array((w0, w1, w2))
    u = ik_step(q, target, x, w, jac, ik_posture, ik_damp, ik_lower, ik_upper, ik_params, ik_limit)
    p, transit, info = grasp_step(
        q, x, rot, jac, goal, goal_rot, posture, k, held, objects, layers, params, lam2, lower, upper
    )
    cmd = u * (1.0 - alpha)
    if alpha != 0.0:  # as the blender: alpha = 0 gives U itself
        cmd += alpha * p
    return u, p, cmd, transit, info


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

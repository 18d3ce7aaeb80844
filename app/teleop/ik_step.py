"""From the user's target to ``U``: one velocity-limited IK step per control tick.

``U = clip(Q + dq)`` with ``dq = dt J^+ [v; w] + dt (I - J^+ J) k_n (q_rest - Q)``, where
``J^+ = J^T (J J^T + l^2 I)^-1``, ``v = k (x* - phi(Q))`` capped at ``max_speed`` (m/s) and
``w = k_r log(R* R^T)`` keeps the gripper pointing down, fingers closing along world y (the
orientation of the start and of every grasp pose). Each joint moves at most ``max_joint_speed / rate_hz`` per tick.

The numbers after the kinematics pass and ``log3`` run compiled (:mod:`app.teleop.ik_step_core`,
the same operations in the same order: the same ``U`` bit for bit); ``compiled=False`` runs the
reference below, in Python.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv

from app.robot.kinematics import Kinematics, downward_rotation
from app.teleop.ik_step_core import ik_step

_F64 = np.dtype(np.float64)

GAIN_PER_S = 5.0
"""``k``: the TCP's speed toward its target is ``k`` times the distance (below ``max_speed``)."""


class IKStep:
    """Velocity-limited damped-least-squares step of the TCP toward a target position."""

    def __init__(
        self,
        kinematics: Kinematics,
        *,
        rate_hz: float,
        max_speed: float = 0.3,
        max_joint_speed: float = 1.0,
        gain: float = GAIN_PER_S,
        rotation_gain: float = 3.0,
        max_angular_speed: float = 1.0,
        damping: float = 1e-3,
        posture: np.ndarray | None = None,
        posture_gain: float = 0.5,
        rotation: np.ndarray | None = None,
        compiled: bool = True,
    ) -> None:
        self.kin = kinematics
        self.dt = 1.0 / rate_hz
        self.max_speed = max_speed
        self.max_joint_step = max_joint_speed * self.dt
        self.gain = gain
        self.rotation_gain = rotation_gain
        self.max_angular_speed = max_angular_speed
        self._damp = damping * np.eye(6)
        self.posture = None if posture is None else np.asarray(posture, dtype=float).copy()
        self.posture_gain = posture_gain
        self.rotation = downward_rotation(0.0) if rotation is None else np.asarray(rotation)
        self._z = np.zeros(kinematics.nq)  # scratch: posture velocity times dt
        self.compiled = compiled
        # the compiled step's numbers (ik_step_core's params), fixed when built
        self._params = np.array(
            (
                self.dt,
                gain,
                rotation_gain,
                max_angular_speed,
                posture_gain,
                self.max_joint_step,
                float(self.posture is not None),
            )
        )
        self._posture = np.empty(0) if self.posture is None else self.posture

    def __call__(
        self,
        q: np.ndarray,
        target: np.ndarray,
        *,
        rotation: np.ndarray | None = None,
        max_speed: float | None = None,
    ) -> np.ndarray:
        """Next configuration ``U`` (7,) moving the TCP from ``phi(q)`` toward ``target`` (3,)."""
        if not self.compiled:
            return self._reference(q, target, rotation=rotation, max_speed=max_speed)
        kin = self.kin
        if type(q) is not np.ndarray or q.dtype != _F64:
            q = np.asarray(q, dtype=np.float64)
        if type(target) is not np.ndarray or target.dtype != _F64:
            target = np.asarray(target, dtype=np.float64)
        x, rotation_now, jac = kin.pose_and_jacobian(q)
        rot = self.rotation if rotation is None else rotation
        return ik_step(
            q,
            target,
            x,
            pin.log3(rot.dot(rotation_now.T)),
            jac,
            self._posture,
            self._damp,
            kin.lower,
            kin.upper,
            self._params,
            float(self.max_speed if max_speed is None else max_speed),
        )

    def kernel_inputs(self) -> tuple[np.ndarray, ...]:
        """What a fused compiled step hands :func:`~app.teleop.ik_step_core.ik_step` besides
        ``Q``, the target and the kinematics pass, up to ``max_speed``: ``(R*, posture, l^2 I,
        lower, upper, params)``, fixed when built (as ``params``)."""
        return (
            np.ascontiguousarray(self.rotation, dtype=np.float64),
            self._posture,
            self._damp,
            self.kin.lower,
            self.kin.upper,
            self._params,
        )

    def _reference(
        self,
        q: np.ndarray,
        target: np.ndarray,
        *,
        rotation: np.ndarray | None = None,
        max_speed: float | None = None,
    ) -> np.ndarray:
        """``__call__`` in Python: the reference the compiled step is tested equal to."""
        kin = self.kin
        dt = self.dt
        # one kinematics pass, shared with whatever asks at the same Q next (the tick's policy)
        x, rotation_now, jac = kin.pose_and_jacobian(q)
        # the twist [v; w] (scaled by dt, so the solve yields dq directly) in scalars
        ex, ey, ez = (target - x).tolist()
        en = math.sqrt(ex * ex + ey * ey + ez * ez)
        limit = self.max_speed if max_speed is None else max_speed
        sv = (self.gain if self.gain * en <= limit else limit / en) * dt
        rot = self.rotation if rotation is None else rotation
        rx, ry, rz = pin.log3(rot.dot(rotation_now.T)).tolist()
        rn = math.sqrt(rx * rx + ry * ry + rz * rz)
        sw = self.rotation_gain
        if sw * rn > self.max_angular_speed:
            sw = self.max_angular_speed / rn
        sw *= dt
        twist = np.array((sv * ex, sv * ey, sv * ez, sw * rx, sw * ry, sw * rz))
        z = None
        if self.posture is not None:
            # dq = J+ twist + (I - J+ J) z  =  z + J+ (twist - J z), z the posture velocity
            z = np.subtract(self.posture, q, out=self._z)
            z *= self.posture_gain * dt
            twist -= jac.dot(z)
        jjt = jac.dot(jac.T)  # ndarray.dot: less call overhead than @ on these small arrays
        jjt += self._damp
        _, y, info = dposv(jjt, twist, overwrite_a=1)  # (J J^T + l^2 I) y = twist
        if info != 0:  # pragma: no cover - J J^T + l^2 I is positive definite
            return q.copy()
        dq = jac.T.dot(y)
        if z is not None:
            dq += z
        biggest = max(map(abs, dq.tolist()))
        if biggest > self.max_joint_step:
            dq *= self.max_joint_step / biggest
        dq += q
        return np.minimum(np.maximum(dq, kin.lower, out=dq), kin.upper, out=dq)

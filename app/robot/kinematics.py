"""Pinocchio kinematics of the arm: forward kinematics, Jacobian and inverse kinematics.

The model is the same URDF MuJoCo simulates, reduced to the seven arm joints (the fingers do
not move the tool centre point, TCP). Quaternions are returned w, x, y, z (MuJoCo's order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

TCP_FRAME = "panda_hand_tcp"
FINGER_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")


def downward_rotation(psi: float) -> np.ndarray:
    """TCP rotation with z pointing down and x at bearing ``psi`` in the table plane.

    Columns ``[x, y, z] = [(cos psi, sin psi, 0), (sin psi, -cos psi, 0), (0, 0, -1)]``.
    """
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class IKResult:
    """Result of ``Kinematics.ik``: the configuration and how far its TCP is from the goal."""

    q: np.ndarray
    converged: bool
    position_error: float
    orientation_error: float
    iterations: int


class Kinematics:
    """FK ``phi(q)``, world-aligned Jacobian ``J(q) = [J_v; J_w]`` (6x7) and damped IK of the TCP.

    Not thread-safe (one pinocchio ``Data`` per instance): give each thread its own ``copy()``.
    """

    def __init__(self, urdf: str, *, tcp_frame: str = TCP_FRAME) -> None:
        full = pin.buildModelFromXML(urdf)
        locked = [full.getJointId(name) for name in FINGER_JOINTS if full.existJointName(name)]
        self.model = pin.buildReducedModel(full, locked, pin.neutral(full)) if locked else full
        self.data = self.model.createData()
        self.frame_id = self.model.getFrameId(tcp_frame)
        self.nq = self.model.nq
        self.lower = np.array(self.model.lowerPositionLimit, dtype=float)
        self.upper = np.array(self.model.upperPositionLimit, dtype=float)
        self.joint_names = tuple(self.model.names[1:])
        self._urdf = urdf
        self._tcp = tcp_frame
        self._pose_q = b""  # the configuration of the last pose_and_jacobian pass (bytes)
        self._pose: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._placement = self.data.oMf[self.frame_id]  # a reference: each pass updates it

    def copy(self) -> Kinematics:
        other = object.__new__(Kinematics)
        other.__dict__.update(self.__dict__)
        other.data = self.model.createData()
        other._placement = other.data.oMf[other.frame_id]
        other._pose_q, other._pose = b"", None
        return other

    @property
    def tcp_in_last_joint(self) -> pin.SE3:
        """Placement of the TCP frame in the frame of the last arm joint (constant)."""
        return self.model.frames[self.frame_id].placement

    def fk(self, q: np.ndarray) -> np.ndarray:
        """TCP position ``phi(q)`` (3,), world frame."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.frame_id].translation.copy()

    def fk_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP position (3,) and orientation as a unit quaternion (w, x, y, z)."""
        pin.framesForwardKinematics(self.model, self.data, q)
        placement = self.data.oMf[self.frame_id]
        x, y, z, w = pin.Quaternion(placement.rotation).coeffs()
        return placement.translation.copy(), np.array([w, x, y, z])

    def fk_rotation(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP position (3,) and rotation matrix (3, 3)."""
        pin.framesForwardKinematics(self.model, self.data, q)
        placement = self.data.oMf[self.frame_id]
        return placement.translation.copy(), placement.rotation.copy()

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """``J(q)`` (6, 7): TCP linear then angular velocity, world-aligned axes, per joint rate."""
        return pin.computeFrameJacobian(
            self.model, self.data, q, self.frame_id, pin.LOCAL_WORLD_ALIGNED
        )

    def pose_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (3,), rotation (3, 3) and ``J(q)`` (6, 7) from one kinematics pass.

        The last pass is kept: asked again at the same ``q`` (a control tick's IK step and its
        policy both start from ``Q``), it returns the same arrays. They are shared: read them,
        never write to them.
        """
        key = q.tobytes()
        pose = self._pose
        if key == self._pose_q and pose is not None:
            return pose
        jac = pin.computeFrameJacobian(
            self.model, self.data, q, self.frame_id, pin.LOCAL_WORLD_ALIGNED
        )
        placement = self._placement  # data.oMf[frame_id], updated by the pass
        pose = self._pose = (placement.translation.copy(), placement.rotation.copy(), jac)
        self._pose_q = key
        return pose

    def chain(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The model as the compiled kernel takes it (``app.robot.kinematics_core``): per joint
        its placement's rotation (row-major), translation and axis (0, 1, 2: x, y, z), and the
        TCP's placement in the last joint; ``None`` unless the arm is a serial chain of
        revolute joints about x, y or z."""
        model = self.model
        axes = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}
        rows = []
        for i in range(1, model.njoints):
            axis = axes.get(model.joints[i].shortname())
            if axis is None or model.parents[i] != i - 1 or model.joints[i].idx_q != i - 1:
                return None
            m = model.jointPlacements[i]
            rows.append([*m.rotation.reshape(-1).tolist(), *m.translation.tolist(), axis])
        frame = model.frames[self.frame_id]
        if len(rows) != self.nq or frame.parentJoint != model.njoints - 1:
            return None
        tcp = frame.placement
        return (
            np.array(rows, dtype=np.float64),
            np.array([*tcp.rotation.reshape(-1).tolist(), *tcp.translation.tolist()]),
        )

    def ik(
        self,
        position: np.ndarray,
        *,
        rotation: np.ndarray | None = None,
        q0: np.ndarray,
        posture: np.ndarray | None = None,
        tol: float = 1e-4,
        rot_tol: float = 1e-3,
        max_iters: int = 300,
        damping: float = 1e-3,
    ) -> IKResult:
        """Damped least squares ``dq = J^T (J J^T + l^2 I)^-1 e``, null-space pull to ``posture``.

        ``e`` stacks the position error and ``log3(R_goal R^T)`` (when ``rotation`` is given);
        iterates stay inside the joint limits.
        """
        position = np.asarray(position, dtype=float)
        q = np.clip(np.asarray(q0, dtype=float).copy(), self.lower, self.upper)
        posture = q.copy() if posture is None else np.asarray(posture, dtype=float)
        rows = slice(0, 6) if rotation is not None else slice(0, 3)
        pos_err = rot_err = np.inf
        for it in range(1, max_iters + 1):
            x, rot, jac = self.pose_and_jacobian(q)
            e_p = position - x
            pos_err = float(np.linalg.norm(e_p))
            if rotation is not None:
                e_r = pin.log3(rotation @ rot.T)
                rot_err = float(np.linalg.norm(e_r))
                err = np.concatenate([e_p, e_r])
            else:
                rot_err = 0.0
                err = e_p
            if pos_err < tol and rot_err < rot_tol:
                return IKResult(q, True, pos_err, rot_err, it)
            j = jac[rows]
            jjt = j @ j.T + damping * np.eye(j.shape[0])
            j_pinv = j.T @ np.linalg.solve(jjt, np.eye(j.shape[0]))
            dq = j_pinv @ err
            if pos_err > 20 * tol:  # near the goal the damped projector leaks: pure task steps
                dq += 0.1 * (np.eye(self.nq) - j_pinv @ j) @ (posture - q)
            norm = np.linalg.norm(dq)
            if norm > 0.3:
                dq *= 0.3 / norm
            q = np.clip(q + dq, self.lower, self.upper)
        return IKResult(q, False, pos_err, rot_err, max_iters)

"""The control step of the study's configuration in one compiled call.

A trial's ``U`` is an IK step toward the steered target and its command the blend
``(1 - alpha) U + alpha P``, ``P`` the policy's step toward G* (``app.trial.trial``). With the
stock components -- the compiled :class:`~app.teleop.ik_step.IKStep`, the compiled
:class:`~app.blending.policy_grasp.GraspApproachPolicy` on the same arm, an arbitration that
keeps no state -- :class:`FusedControl` works out ``U``, ``P`` and the command in one kernel
(:mod:`app.trial.fused_control_core`: one kinematics pass, no Python between the parts), the
blender doing the rest as in :meth:`~app.blending.PolicyBlender.step`
(:meth:`~app.blending.PolicyBlender.step_joint`). Any other configuration takes the
components' own calls (:func:`fused_control` gives ``None``).

The numbers: the kernel's kinematics pass is pinocchio's chain composed in compiled code, not
pinocchio's own call, and its damped least squares run in plain loops, not BLAS and LAPACK, so
``U``, ``P`` and the command may differ from the components' in the last bits
(``tests/test_fused_control.py`` bounds it by 1e-12 on every tick of whole trials; over the 24
trials of ``benchmarks/trial_dump.py`` the logged columns moved by at most 5e-14, the outcomes
and events the same).
"""

from __future__ import annotations

import numpy as np

from app.blending import PolicyBlender
from app.blending.blend import BlendRecord
from app.blending.errors import InvalidInputError
from app.blending.policy_grasp import GraspApproachPolicy
from app.teleop.ik_step import IKStep
from app.trial.fused_control_core import control_step

__all__ = ["FusedControl", "fused_control"]


def fused_control(ik: object, blender: PolicyBlender) -> FusedControl | None:
    """A :class:`FusedControl` for ``ik`` and ``blender`` when they are the stock components
    (see the module docstring), else ``None``."""
    policy = blender.policy
    if type(ik) is not IKStep or not ik.compiled:
        return None
    if type(policy) is not GraspApproachPolicy or not policy.compiled:
        return None
    if policy.arm.pose_jacobian != ik.kin.pose_and_jacobian:  # the same arm, the same pass
        return None
    chain = ik.kin.chain()
    if chain is None:
        return None
    return FusedControl(ik, blender, policy, chain)


class FusedControl:
    """``step(Q, target, x=..., robot_x=...) -> (U, BlendRecord)``: ``ik(Q, target)`` then
    ``blender.step(Q, U, x=x, robot_x=robot_x)`` in one compiled call (the blender's
    ``arbitration`` may be swapped meanwhile: a stateful one takes the components' calls)."""

    def __init__(
        self,
        ik: IKStep,
        blender: PolicyBlender,
        policy: GraspApproachPolicy,
        chain: tuple[np.ndarray, np.ndarray],
    ) -> None:
        self.ik = ik
        self.blender = blender
        self.policy = policy
        self._chain = chain
        self._ik_inputs = ik.kernel_inputs()
        self._q = self._target = self._u = np.empty(0)

    def step(
        self, q: np.ndarray, target: np.ndarray, *, x: np.ndarray, robot_x: np.ndarray
    ) -> tuple[np.ndarray, BlendRecord]:
        """``U`` toward ``target`` (3,) and the blender's record of this tick (``Q``, ``target``
        and ``x`` float arrays)."""
        blender = self.blender
        if blender.stateful or blender.policy is not self.policy:
            u = self.ik(q, target)
            return u, blender.step(q, u, x=x, robot_x=robot_x)
        self._q, self._target = q, target
        rec = blender.step_joint(q, x=x, robot_x=robot_x, act=self._act)
        return self._u, rec

    def _act(self, k: int, alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """``(U, P, command, finite)`` toward goal ``k`` with ``alpha``
        (``PolicyBlender.step_joint``)."""
        policy = self.policy
        args = policy.kernel_inputs(k)
        out, transit, info, finite = control_step(
            self._q,
            self._target,
            alpha,
            *self._chain,
            *self._ik_inputs,
            float(self.ik.max_speed),
            *args,
        )
        if info != 0:  # pragma: no cover - J J^T + lambda^2 I is positive definite
            raise InvalidInputError("the kinematics pass gave a Jacobian that is not finite")
        policy.note_transit(k, transit)
        u = self._u = out[0]
        return u, out[1], out[2], finite

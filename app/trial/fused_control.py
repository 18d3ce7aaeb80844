"""The control step of the study's configuration in one compiled call.

A trial's ``U`` is an IK step toward the steered target and its command the blend
``(1 - alpha) U + alpha P``, ``P`` the policy's step toward G* (``app.trial.trial``). With the
stock components -- the compiled :class:`~app.teleop.ik_step.IKStep`, the compiled
:class:`~app.blending.policy_grasp.GraspApproachPolicy` on the same arm, an arbitration that
keeps no state -- :class:`FusedControl` works out ``U``, ``P`` and the command in one kernel
(:mod:`app.trial.fused_control_core`: one kinematics pass, no Python between the parts). With
a stock prediction, confidence and arbitration too (amnesic, memory-based or oracle; distance
or probability; none, timid, aggressive or linear: ``app.blending.assess_core``) the same call
works out ``P(G | xi)``, ``G*``, the confidence, ``alpha`` and the motion agreement first
(:meth:`~app.blending.PolicyBlender.step_compiled`); with others the blender works them out
and the kernel takes ``G*`` and ``alpha`` (:meth:`~app.blending.PolicyBlender.step_joint`).
Any other IK step or policy takes the components' own calls (:func:`fused_control` gives
``None``).

The numbers: the kernel's kinematics pass is pinocchio's chain composed in compiled code, not
pinocchio's own call, and its damped least squares run in plain loops, not BLAS and LAPACK, so
``U``, ``P`` and the command may differ from the components' in the last bits
(``tests/test_fused_control.py`` bounds it by 1e-12 on every tick of whole trials); the
softmax's exponential is the C library's, not numpy's, so ``P(G | xi)`` may differ by an ulp
or two (a probability confidence with it); ``G*``, a distance confidence, ``alpha``, the
rationality and the motion agreement are the components' bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from app.blending import PolicyBlender
from app.blending.assess_core import GIVEN
from app.blending.blend import BlendRecord
from app.blending.errors import InvalidInputError
from app.blending.policy_grasp import GraspApproachPolicy
from app.teleop.ik_step import IKStep
from app.trial.fused_control_core import control_step, pack_arm, pack_goals

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
    ``blender.step(Q, U, x=x, robot_x=robot_x)`` in one compiled call -- with prediction,
    confidence and arbitration in it too when they are stock kinds
    (:meth:`~app.blending.PolicyBlender.step_compiled`), else worked out by the blender first
    (:meth:`~app.blending.PolicyBlender.step_joint`). The blender's components may be swapped
    meanwhile: a stateful arbitration or another policy takes the components' calls."""

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
        self._arm = pack_arm((*chain, *ik.kernel_inputs(), *policy.kernel_constants()))
        self._q = self._target = self._u = np.empty(0)
        self._goals: tuple[np.ndarray, ...] = ()
        self._goal_set = (np.empty(0), np.empty(0, dtype=bool))  # packed, and the hysteresis
        self._goals_packed: object = None  # the goals they were packed from

    def step(
        self, q: np.ndarray, target: np.ndarray, *, x: np.ndarray, robot_x: np.ndarray
    ) -> tuple[np.ndarray, BlendRecord]:
        """``U`` toward ``target`` (3,) and the blender's record of this tick (``Q``, ``target``,
        ``x`` and ``robot_x`` float arrays)."""
        blender, policy = self.blender, self.policy
        goals = policy.kernel_goals()
        if goals is None or blender.policy is not policy or blender.stateful:
            u = self.ik(q, target)
            return u, blender.step(q, u, x=x, robot_x=robot_x)
        self._q, self._target, self._goals = q, target, goals
        if goals is not self._goals_packed:  # the same tuple until the goals change
            self._goals_packed = goals
            rows, rots, postures, approaching, objects = goals
            self._goal_set = (pack_goals(rows, rots, postures, objects), approaching)
        if blender.compiled_numbers() is not None:
            rec = blender.step_compiled(q, x=x, robot_x=robot_x, act=self._act_all)
        else:
            rec = blender.step_joint(q, x=x, robot_x=robot_x, act=self._act)
        return self._u, rec

    def _act_all(self, *assessment: Any) -> tuple[Any, ...]:
        """``(U, P, command, P(G | xi), G*, conf, d, motion agreement, alpha, C(xi_{S->U}),
        finite)`` from ``assess``'s inputs (``PolicyBlender.step_compiled``)."""
        q = self._q
        goals = self._goals
        n = q.shape[0]
        out = np.empty(3 * n + assessment[3].shape[0])  # [U; P; command; P(G | xi)]
        k, flips, info, finite, c, d, motion, alpha, c_su = control_step(
            q, self._target, *assessment, float(self.ik.max_speed), self._arm, *self._goal_set, out
        )
        if info != 0:  # pragma: no cover - J J^T + lambda^2 I is positive definite
            raise InvalidInputError("the kinematics pass gave a Jacobian that is not finite")
        if flips:  # in transit exactly when it was approaching G* (goals[3]): noted
            self.policy.note_transit(k, bool(goals[3][k]))
        u = self._u = out[:n]
        return (
            u,
            out[n : 2 * n],
            out[2 * n : 3 * n],
            out[3 * n :],
            k,
            c,
            d,
            motion,
            alpha,
            c_su,
            finite,
        )

    def _act(self, k: int, alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """``(U, P, command, finite)`` toward goal ``k`` with ``alpha``
        (``PolicyBlender.step_joint``)."""
        q, target = self._q, self._target
        none = _NO_VECTOR
        goals = self._goals
        n = q.shape[0]
        out = np.empty(3 * n + 1)  # [U; P; command; unset]
        _, flips, info, finite, *_ = control_step(
            *(q, target, target, target, none, _ONE_POINT, _ONE_POINT, none, none, target),
            *(_GIVEN, k, alpha, 0.0),
            float(self.ik.max_speed),
            self._arm,
            *self._goal_set,
            out,
        )
        if info != 0:  # pragma: no cover - J J^T + lambda^2 I is positive definite
            raise InvalidInputError("the kinematics pass gave a Jacobian that is not finite")
        if flips:  # as in _act_all
            self.policy.note_transit(k, bool(goals[3][k]))
        u = self._u = out[:n]
        return u, out[n : 2 * n], out[2 * n : 3 * n], finite


_NO_VECTOR = np.empty(0)
_ONE_POINT = np.zeros((1, 3))  # the kernel's P(G | xi) rows, unused when G* is given
_GIVEN = np.array((GIVEN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))

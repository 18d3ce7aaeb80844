"""What a tick reads from the user's input alone, compiled for the stock components.

:meth:`~app.blending.PolicyBlender.assess` in one compiled call, for a blender whose
prediction, confidence and arbitration are of the kinds below (:func:`numbers` says which;
any other takes the components' own calls):

    P(G | x) = exp(-d(x, G) / T) / sum_G' exp(-d(x, G') / T)            amnesic, d Euclidean
    P(G | xi) ∝ exp(-b (C(xi_{S->U}) + ||U - G|| - C(xi*_{S->G}))) P(G)  memory (eq. 9, length)
    P(G | xi) = 1 for the told goal                                     oracle
    G* = argmax_G P(G | xi)   (ties to the lowest index)
    d = ||x - G*||,   conf = max(0, 1 - d / D)  or  conf = P(G* | xi)
    alpha = a(conf)           (none, timid, aggressive, linear: app.blending.arbitration)
    motion agreement = <direction, G* - robot_x> / ||G* - robot_x||

each the very operations of its component, in the same order, with two library functions
reproduced: ``math.dist`` (CPython's scaled, compensated norm: :func:`dist3`) and numpy's
``dot`` of three numbers (fused multiply-adds in sequence: :func:`dot3`). The one difference
is the exponential of the softmax: the C library's here, numpy's own SIMD one in the
components; they differ in the last bit on about 4.6 % of inputs, so the probabilities (and a
confidence read from them) may differ by an ulp or two; ``G*``, the distance confidence,
``alpha`` and the motion agreement come out bit for bit (``tests/test_fused_control.py``).

``app.trial.fused_control_core`` inlines these kernels: its cache is kept per version of every
kernel source (``app.compiled.cache_dir``), so an edit here compiles it afresh.

``nums`` (8,): ``prediction kind, its number (amnesic -1/T), confidence kind, its number
(1/D), arbitration kind, its three numbers`` (:func:`numbers`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from app.compiled import jit
from app.norm_core import vector_norm

from .arbitration import Aggressive, Linear, NoAssistance, Timid
from .confidence import DistanceHinge, ProbabilityConfidence
from .prediction.amnesic import AmnesicPredictor, euclidean
from .prediction.costs import PathLengthCost
from .prediction.memory import MemoryPredictor
from .prediction.oracle import OraclePredictor

__all__ = [
    "GIVEN",
    "assess",
    "dist3",
    "dot3",
    "numbers",
]

GIVEN, ORACLE, AMNESIC, MEMORY = -1.0, 0.0, 1.0, 2.0
"""Prediction kinds (``nums[0]``); ``GIVEN``: ``G*`` and ``alpha`` worked out by the caller."""
DISTANCE, PROBABILITY = 0.0, 1.0
"""Confidence kinds (``nums[2]``)."""
NO_ASSISTANCE, TIMID, AGGRESSIVE, LINEAR = 0.0, 1.0, 2.0, 3.0
"""Arbitration kinds (``nums[4]``)."""


def numbers(predictor: object, confidence: object, arbitration: object) -> np.ndarray | None:
    """``nums`` for these components when each is a stock kind this module computes (the
    predictor in 3-D: amnesic with the Euclidean metric, memory-based with the path-length
    cost, or the oracle; the distance or probability confidence; no assistance, timid,
    aggressive or linear arbitration), else ``None``. Read again whenever one of them, or the
    goals, changed (their numbers are fixed once built)."""
    t = type(predictor)
    if t is AmnesicPredictor:
        if predictor.metric is not euclidean or predictor.dim != 3:  # type: ignore[attr-defined]
            return None
        pred = (AMNESIC, -1.0 / predictor.temperature)  # type: ignore[attr-defined]
    elif t is MemoryPredictor:
        if type(predictor.cost) is not PathLengthCost or predictor.dim != 3:  # type: ignore[attr-defined]
            return None
        pred = (MEMORY, 0.0)
    elif t is OraclePredictor:
        pred = (ORACLE, 0.0)
    else:
        return None
    t = type(confidence)
    if t is DistanceHinge:
        conf = (DISTANCE, 1.0 / confidence.D)  # type: ignore[attr-defined]
    elif t is ProbabilityConfidence:
        conf = (PROBABILITY, 0.0)
    else:
        return None
    a: Any = arbitration
    t = type(a)
    if t is NoAssistance:
        arb = (NO_ASSISTANCE, 0.0, 0.0, 0.0)
    elif t is Timid:
        arb = (TIMID, a.alpha_max, a.saturation, a.alpha_max / a.saturation)
    elif t is Aggressive:
        arb = (AGGRESSIVE, a.threshold, a.alpha_high, 0.0)
    elif t is Linear:
        arb = (LINEAR, a.alpha_min, a.alpha_max, 0.0)
    else:
        return None
    return np.array((*pred, *conf, *arb), dtype=np.float64)


@intrinsic
def _fma(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
    """``a b + c`` rounded once (LLVM's ``fma``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@jit
def dot3(a: np.ndarray, b: np.ndarray) -> float:
    """``a . b`` of two 3-vectors as numpy's ``dot`` gives it (BLAS: ``fma(a2, b2, fma(a1, b1,
    a0 b0))``)."""
    return _fma(a[2], b[2], _fma(a[1], b[1], a[0] * b[0]))


@jit
def dist3(a: np.ndarray, b: np.ndarray) -> float:
    """``||a - b||`` of two 3-vectors as ``math.dist`` gives it (``app.norm_core``)."""
    return vector_norm(abs(a[0] - b[0]), abs(a[1] - b[1]), abs(a[2] - b[2]))


@jit
def _softmax(z: np.ndarray) -> int:
    """``z <- exp(z - max z) / sum exp(z - max z)`` in place (``softmax``); the argmax, ``-1``
    when the largest is not finite."""
    k = 0
    top = z[0]
    for j in range(1, z.shape[0]):
        if z[j] > top:
            top, k = z[j], j
    if not math.isfinite(top):
        return -1
    s = 0.0  # numpy's add.reduce adds in sequence up to 8 numbers (pairwise beyond: ulps)
    for j in range(z.shape[0]):
        z[j] = math.exp(z[j] - top)
        s += z[j]
    for j in range(z.shape[0]):
        z[j] /= s
    return k


@jit
def assess(
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
    c_su: float,
    b: float,
    probs: np.ndarray,
) -> tuple[int, float, float, float, float, float]:
    """``(G*, conf, d, motion agreement, alpha, C(xi_{S->U}))`` for the input ``x`` with the
    robot at ``robot_x``; ``probs`` (n,) gets ``P(G | xi)``.

    ``points``: the goals (the blender's, for ``d`` and the heading); ``direction``: the user's
    latest motion (empty before they moved); prediction's inputs -- oracle: ``k`` its goal;
    amnesic: ``pred_points``; memory: ``pred_points``,
    ``pred_vec`` ``log P(G)``, ``pred_vec2`` ``C(xi*_{S->G})``, ``prev`` the last input,
    ``c_su`` ``C(xi_{S->U})`` before this input, ``b`` the rationality. ``G*`` is ``-1`` when
    no goal has a finite log-probability (as ``softmax`` raises)."""
    pkind = nums[0]
    n = probs.shape[0]
    if pkind == ORACLE:  # told the goal k: P(k) = 1, 0 for the others
        for j in range(n):
            probs[j] = 1.0 if j == k else 0.0
    elif pkind == AMNESIC:
        px, py, pz, s = x[0], x[1], x[2], nums[1]
        for j in range(n):
            dx, dy, dz = pred_points[j, 0] - px, pred_points[j, 1] - py, pred_points[j, 2] - pz
            probs[j] = math.sqrt(dx * dx + dy * dy + dz * dz) * s
        k = _softmax(probs)
    else:  # MEMORY: z = -b (||x - G|| + C(S->U) - C*(S->G)) + log P(G)
        step = x - prev
        c_su = c_su + math.sqrt(dot3(step, step))
        for j in range(n):
            dx, dy, dz = (
                pred_points[j, 0] - x[0],
                pred_points[j, 1] - x[1],
                pred_points[j, 2] - x[2],
            )
            z = math.sqrt(dx * dx + dy * dy + dz * dz)
            z += c_su
            z -= pred_vec2[j]
            z *= -b
            z += pred_vec[j]
            probs[j] = z
        k = _softmax(probs)
    if k < 0:
        return k, 0.0, 0.0, 0.0, 0.0, c_su
    g = points[k]
    motion = 0.0
    if direction.shape[0] > 0:
        heading = g - robot_x
        hn = math.sqrt(dot3(heading, heading))
        motion = dot3(direction, heading) / hn if hn > 0.0 else 0.0
    d = dist3(x, g)
    if nums[2] == DISTANCE:
        c = 1.0 - d * nums[3]
        c = c if c > 0.0 else 0.0
    else:
        c = probs[k]
    akind, a1, a2, a3 = nums[4], nums[5], nums[6], nums[7]
    if akind == TIMID:  # alpha_max, saturation, alpha_max / saturation
        alpha = a1 if c >= a2 else (a3 * c if c > 0.0 else 0.0)
    elif akind == AGGRESSIVE:  # threshold, alpha_high
        alpha = a2 if c >= a1 else 0.0
    elif akind == LINEAR:  # alpha_min, alpha_max
        cl = 0.0 if c < 0.0 else (1.0 if c > 1.0 else c)
        alpha = a1 + (a2 - a1) * cl
    else:
        alpha = 0.0
    return k, c, d, motion, alpha, c_su

"""Confidence in the prediction, ``conf in [0, 1]`` (section 3.2).

Every measure is a callable ``(prediction: GoalPrediction, distance: float) -> float``;
``distance`` is ``d``, from the user's input to the predicted goal, in the predictor's space.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from ._checks import positive
from .prediction.base import GoalPrediction

__all__ = [
    "Confidence",
    "DistanceHinge",
    "EntropyConfidence",
    "MarginConfidence",
    "ProbabilityConfidence",
]


@runtime_checkable
class Confidence(Protocol):
    def __call__(self, prediction: GoalPrediction, distance: float) -> float: ...


class DistanceHinge:
    """``conf = max(0, 1 - d / D)``: 1 at the predicted goal, 0 from ``D`` away (the study's)."""

    def __init__(self, D: float) -> None:
        self.D = positive(D, name="D")
        self._inv = 1.0 / self.D

    def __call__(self, prediction: GoalPrediction, distance: float) -> float:
        c = 1.0 - distance * self._inv
        return c if c > 0.0 else 0.0

    def __repr__(self) -> str:
        return f"DistanceHinge(D={self.D})"


class ProbabilityConfidence:
    """``conf = P(G* | xi_{S->U})``."""

    def __call__(self, prediction: GoalPrediction, distance: float) -> float:
        return float(prediction.probabilities[prediction.index])

    def __repr__(self) -> str:
        return "ProbabilityConfidence()"


class EntropyConfidence:
    """``conf = 1 - H(P) / log n`` with ``H(P) = -sum_G P(G) log P(G)`` (``0 log 0 = 0``).

    The paper's ``sum_G P log P`` (negative entropy) rescaled to [0, 1]: 1 for a certain
    prediction, 0 for the uniform one. With a single goal the prediction is certain: 1.
    """

    def __call__(self, prediction: GoalPrediction, distance: float) -> float:
        p = prediction.probabilities
        n = p.shape[0]
        if n < 2:
            return 1.0
        nz = p[p > 0.0]
        h = -float(nz.dot(np.log(nz)))
        c = 1.0 - h / math.log(n)
        return min(1.0, max(0.0, c))

    def __repr__(self) -> str:
        return "EntropyConfidence()"


class MarginConfidence:
    """``conf = P(G*) - max_{G != G*} P(G)``; 1 with a single goal."""

    def __call__(self, prediction: GoalPrediction, distance: float) -> float:
        p = prediction.probabilities
        if p.shape[0] < 2:
            return 1.0
        top = float(p[prediction.index])
        if p.shape[0] == 2:
            second = float(p[1 - prediction.index])
        else:
            # second-largest value; with ties for the maximum it equals the maximum (margin 0)
            second = float(np.partition(p, -2)[-2])
        return max(0.0, top - second)

    def __repr__(self) -> str:
        return "MarginConfidence()"

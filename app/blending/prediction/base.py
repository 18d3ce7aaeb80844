"""What every goal predictor returns and shares.

A predictor turns the user's inputs ``xi_{S->U}`` (points in the predictor's space: workspace
positions or configurations) into a probability vector over the goals,
``P(G | xi_{S->U})``, and its argmax ``G* = argmax_G P(G | xi_{S->U})``.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from ..errors import InvalidInputError

__all__ = ["GoalPoints", "GoalPrediction", "Predictor", "softmax"]


class GoalPrediction(NamedTuple):
    """``probabilities``: ``(n,)``, non-negative, summing to 1; ``index``: their argmax."""

    probabilities: np.ndarray
    index: int


@runtime_checkable
class Predictor(Protocol):
    """Goal predictor: ``reset(start)`` at the user's first input S, then ``update(x)`` per tick."""

    @property
    def n_goals(self) -> int: ...

    def reset(self, start: np.ndarray) -> None: ...

    def update(self, x: np.ndarray) -> GoalPrediction: ...


class GoalPoints:
    """Shared by the predictors that hold the goals as points ``(n, d)`` in their space."""

    points: np.ndarray

    @property
    def n_goals(self) -> int:
        return self.points.shape[0]

    @property
    def dim(self) -> int:
        return self.points.shape[1]


def softmax(logits: np.ndarray) -> GoalPrediction:
    """``p_i = exp(l_i - max l) / sum_j exp(l_j - max l)``: normalisation in log space.

    ``logits`` is consumed (overwritten) to save an allocation per tick. Ties go to the lowest
    index.
    """
    k = int(logits.argmax())
    top = float(logits[k])
    if not math.isfinite(top):
        raise InvalidInputError(
            "logits: no goal has a finite log-probability, or one is NaN (inputs too large, "
            "a zero prior everywhere, or a metric/cost returning NaN)"
        )
    logits -= top
    np.exp(logits, out=logits)
    logits /= np.add.reduce(logits)  # logits.sum() without its Python wrapper (per tick)
    return GoalPrediction(logits, k)


def check_x(x: object, dim: int, name: str = "x") -> np.ndarray:
    """Per-tick check of one input point: shape ``(dim,)`` and finite (cheap)."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.shape != (dim,):
        raise InvalidInputError(f"{name}: expected shape ({dim},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise InvalidInputError(f"{name}: contains NaN or infinite values: {arr!r}")
    return arr

"""Goal prediction: ``P(G | xi_{S->U})`` and ``G* = argmax_G``.

Amnesic (current input only), memory-based (eq. 9), Laplace (eq. 8), and oracle.
"""

from .amnesic import AmnesicPredictor, Metric, euclidean
from .base import GoalPrediction, Predictor, softmax
from .costs import Cost, HessianCost, PathLengthCost, SquaredVelocityCost
from .laplace import LaplacePredictor
from .memory import MemoryPredictor
from .oracle import OraclePredictor

__all__ = [
    "AmnesicPredictor",
    "Cost",
    "GoalPrediction",
    "HessianCost",
    "LaplacePredictor",
    "MemoryPredictor",
    "Metric",
    "OraclePredictor",
    "PathLengthCost",
    "Predictor",
    "SquaredVelocityCost",
    "euclidean",
    "softmax",
]

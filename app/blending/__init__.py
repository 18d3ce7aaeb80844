"""The policy-blending formalism for shared control (Dragan & Srinivasa 2013), pure numpy.

Per control tick: goal prediction ``P(G | xi_{S->U})`` -> confidence ``c`` -> arbitration
``alpha(c)`` -> trajectory prediction ``P`` -> ``command = (1 - alpha) U + alpha P``.
"""

from .arbitration import (
    Aggressive,
    Arbitration,
    FunctionArbitration,
    Linear,
    NoAssistance,
    PiecewiseLinear,
    Timid,
    check_arbitration,
    is_adversarial,
)
from .blend import BlendRecord, PolicyBlender, blend
from .confidence import (
    Confidence,
    DistanceHinge,
    EntropyConfidence,
    MarginConfidence,
    ProbabilityConfidence,
)
from .config import (
    arbitration_from_config,
    confidence_from_config,
    policy_from_config,
    predictor_from_config,
)
from .errors import BlendingError, ConfigError, InvalidArbitrationError, InvalidInputError
from .goals import GoalSet
from .policy import Policy, StraightLinePolicy, WorkspaceLinePolicy
from .prediction import (
    AmnesicPredictor,
    Cost,
    GoalPrediction,
    HessianCost,
    LaplacePredictor,
    MemoryPredictor,
    Metric,
    OraclePredictor,
    PathLengthCost,
    Predictor,
    SquaredVelocityCost,
    euclidean,
    softmax,
)

__all__ = [
    "Aggressive",
    "AmnesicPredictor",
    "Arbitration",
    "BlendRecord",
    "BlendingError",
    "Confidence",
    "ConfigError",
    "Cost",
    "DistanceHinge",
    "EntropyConfidence",
    "FunctionArbitration",
    "GoalPrediction",
    "GoalSet",
    "HessianCost",
    "InvalidArbitrationError",
    "InvalidInputError",
    "LaplacePredictor",
    "Linear",
    "MarginConfidence",
    "MemoryPredictor",
    "Metric",
    "NoAssistance",
    "OraclePredictor",
    "PathLengthCost",
    "PiecewiseLinear",
    "Policy",
    "PolicyBlender",
    "Predictor",
    "ProbabilityConfidence",
    "SquaredVelocityCost",
    "StraightLinePolicy",
    "Timid",
    "WorkspaceLinePolicy",
    "arbitration_from_config",
    "blend",
    "check_arbitration",
    "confidence_from_config",
    "euclidean",
    "is_adversarial",
    "policy_from_config",
    "predictor_from_config",
    "softmax",
]

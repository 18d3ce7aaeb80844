"""The policy-blending formalism for shared control (Dragan & Srinivasa 2013), pure numpy.

Per control tick: goal prediction ``P(G | xi_{S->U})`` -> confidence ``c`` -> arbitration
``alpha(c)`` -> trajectory prediction ``P`` -> ``command = (1 - alpha) U + alpha P``.

Example (the study's "wrong" condition, timid mode)::

    goals = GoalSet(["box", "bottle"], positions, configurations=goal_qs)
    blender = PolicyBlender(
        goals=goals,
        predictor=predictor_from_config({"kind": "amnesic", "space": "workspace"}, points=goals),
        confidence=confidence_from_config({"kind": "distance", "D": 0.4}),
        arbitration=arbitration_from_config({"kind": "timid", "alpha_max": 0.5,
                                             "saturation": 0.7}),
        policy=policy_from_config({"kind": "straight_line", "max_speed": 1.0}, rate_hz=100),
        space="workspace",
    )
    blender.reset(start_target)                      # S, in the predictor's space
    record = blender.step(q, u, x=user_target)       # per tick; record.command -> actuators

Modules: goals, goal_moves (goals that follow moved objects, logged for replay), prediction/ (base, amnesic, memory, laplace, oracle, costs), confidence,
arbitration, policy, blend, config (factories from protocol tables), errors, reference (exact
soft value iteration on a 2-D grid, to test eq. 9 against).
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
from .goal_moves import GoalMoves, moved_goals
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
    "GoalMoves",
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
    "moved_goals",
    "policy_from_config",
    "predictor_from_config",
    "softmax",
]

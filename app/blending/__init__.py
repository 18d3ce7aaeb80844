"""The policy-blending formalism for shared control (Dragan & Srinivasa 2013), pure numpy.

Per control tick: goal prediction ``P(G | xi_{S->U})`` -> confidence ``c`` -> arbitration
``alpha(c)`` -> trajectory prediction ``P`` -> ``command = (1 - alpha) U + alpha P``.

Example: a 2-D arm between two goals, "aggressive" arbitration, built from protocol tables::

    >>> from app.blending import (GoalSet, PolicyBlender, arbitration_from_config,
    ...     confidence_from_config, policy_from_config, predictor_from_config)
    >>> goals = GoalSet(["box", "bottle"], [[1, 0, 0], [0, 1, 0]],
    ...                 configurations=[[1, 0], [0, 1]])
    >>> blender = PolicyBlender(
    ...     goals=goals,
    ...     predictor=predictor_from_config({"kind": "amnesic", "space": "configuration"},
    ...                                     points=goals),
    ...     confidence=confidence_from_config({"kind": "distance", "D": 1.0}),
    ...     arbitration=arbitration_from_config({"kind": "aggressive", "threshold": 0.3}),
    ...     policy=policy_from_config({"kind": "straight_line", "max_speed": 1.0}, rate_hz=10),
    ...     space="configuration",
    ... )
    >>> blender.reset([0.0, 0.0])                     # S, the user's first input
    >>> rec = blender.step([0.5, 0.1], [0.6, 0.1])    # robot Q, the user's next U
    >>> goals.names[rec.predicted], round(rec.confidence, 2), rec.alpha
    ('box', 0.59, 1.0)
    >>> rec.command.round(3).tolist()                 # alpha = 1: the robot's P
    [0.598, 0.08]

Every component kind is declared once in :mod:`app.blending.spec` (the built-in ones in
:mod:`app.blending.kinds`); :func:`register` adds a new one, which the builders, the protocol
loader and the docs then know. Modules: goals, goal_moves, prediction/ (amnesic, memory eq. 9,
laplace eq. 8, oracle, costs, rationality: the user's rationality estimated online),
confidence, arbitration, adaptive (stateful arbitration: yielding, user_confidence), policy
(straight lines), policy_grasp (pre-grasp, approach along the gripper axis, clearance), blend,
spec, kinds, config, errors, reference (exact soft value iteration on a 2-D grid, to test eq. 9
against).
"""

from .adaptive import StatefulArbitration, TickSignals, UserConfidence, Yielding
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
from .policy_grasp import ArmModel, GraspApproachPolicy, HandLayer, reach_below
from .prediction import (
    AmnesicPredictor,
    GoalPrediction,
    LaplacePredictor,
    MemoryPredictor,
    OraclePredictor,
    PathLengthCost,
    Predictor,
    SquaredVelocityCost,
)
from .prediction.rationality import RationalityEstimator
from .spec import BuildContext, Kind, Param, register, unregister

__all__ = [
    "Aggressive",
    "AmnesicPredictor",
    "Arbitration",
    "ArmModel",
    "BlendRecord",
    "BlendingError",
    "BuildContext",
    "Confidence",
    "ConfigError",
    "DistanceHinge",
    "EntropyConfidence",
    "FunctionArbitration",
    "GoalMoves",
    "GoalPrediction",
    "GoalSet",
    "GraspApproachPolicy",
    "HandLayer",
    "InvalidArbitrationError",
    "InvalidInputError",
    "Kind",
    "LaplacePredictor",
    "Linear",
    "MarginConfidence",
    "MemoryPredictor",
    "NoAssistance",
    "OraclePredictor",
    "Param",
    "PathLengthCost",
    "PiecewiseLinear",
    "Policy",
    "PolicyBlender",
    "Predictor",
    "ProbabilityConfidence",
    "RationalityEstimator",
    "SquaredVelocityCost",
    "StatefulArbitration",
    "StraightLinePolicy",
    "TickSignals",
    "Timid",
    "UserConfidence",
    "WorkspaceLinePolicy",
    "Yielding",
    "arbitration_from_config",
    "blend",
    "check_arbitration",
    "confidence_from_config",
    "is_adversarial",
    "moved_goals",
    "policy_from_config",
    "predictor_from_config",
    "reach_below",
    "register",
    "unregister",
]

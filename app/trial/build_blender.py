"""A trial's ``PolicyBlender``, built from its configuration (components given as tables are built
by their kinds' factories, ``app.blending``; built components are taken as they are)."""

from __future__ import annotations

from collections.abc import Mapping

from app.blending import (
    NoAssistance,
    PolicyBlender,
    arbitration_from_config,
    confidence_from_config,
    policy_from_config,
    predictor_from_config,
)
from app.robot.kinematics import Kinematics
from app.robot.scene import Scene
from app.trial.config import TrialConfig
from app.trial.errors import TrialConfigError

__all__ = ["build_blender"]


def build_blender(config: TrialConfig, scene: Scene, kinematics: Kinematics) -> PolicyBlender:
    """The blender of ``config`` over ``scene``'s goals: each component given as a table is built
    by its kind's factory (``app.blending``), no arbitration means no assistance; the trial
    predicts from the user's target (``prediction.space = "workspace"``)."""
    goals = scene.goals
    prediction = config.prediction
    space = "workspace"
    if isinstance(prediction, Mapping):
        space = str(prediction.get("space", "workspace"))
        prediction = predictor_from_config(
            dict(prediction),
            points=goals,
            where="prediction",
            target=scene.target_index,
            rate_hz=config.rate_hz,
        )
    confidence = config.confidence
    if isinstance(confidence, Mapping):
        confidence = confidence_from_config(dict(confidence), where="confidence")
    arbitration = config.arbitration
    if arbitration is None:
        arbitration = NoAssistance()
    elif isinstance(arbitration, Mapping):
        arbitration = arbitration_from_config(
            dict(arbitration), where="arbitration", rate_hz=config.rate_hz
        )
    policy = config.policy
    if isinstance(policy, Mapping):
        policy = policy_from_config(
            dict(policy),
            rate_hz=config.rate_hz,
            where="policy",
            arm=scene.arm_model(kinematics),
        )
    if space != "workspace":
        raise TrialConfigError(
            "prediction.space: the trial predicts from the user's target, use 'workspace'"
        )
    return PolicyBlender(
        goals=goals,
        predictor=prediction,
        confidence=confidence,
        arbitration=arbitration,
        policy=policy,
        space="workspace",
    )

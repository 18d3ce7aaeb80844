"""The blender's per-tick values reach the trial as a named record (``BlendTick``), the same the
observation and the tick records carry."""

from __future__ import annotations

import math

import numpy as np

from app.teleop import ScriptedInput
from app.trial import BlendTick, Trial
from study.protocol import trial_config_from_protocol


def test_each_tick_the_trial_keeps_the_blenders_values_by_name(protocol_path) -> None:
    config = trial_config_from_protocol(protocol_path, "easy-right", "aggressive")
    trial = Trial(config, ScriptedInput(seed=0))
    before = trial.blend
    assert isinstance(before, BlendTick) and before.predicted == -1
    assert math.isnan(before.rationality) and before.alpha == 0.0
    for _ in range(120):
        record = trial.tick()
        assert record is not None
        blend = trial.blend
        assert (record.alpha, record.confidence, record.predicted) == (
            blend.alpha,
            blend.confidence,
            blend.predicted,
        )
        assert record.probabilities is blend.probabilities
        assert record.motion_agreement == blend.motion_agreement
        seen = trial.observation()
        assert (seen.alpha, seen.predicted) == (blend.alpha, blend.predicted)
    assert trial.blend.predicted in (0, 1) and np.isclose(trial.blend.probabilities.sum(), 1.0)

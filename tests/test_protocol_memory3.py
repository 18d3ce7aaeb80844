"""The format-reach example protocols/memory3.toml: its memory-based condition is usable."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.teleop import ScriptedInput
from app.trial import run_trial
from study.protocol import load_protocol

MEMORY3 = Path(__file__).resolve().parents[1] / "protocols" / "memory3.toml"


@pytest.mark.parametrize("mode", ["timid", "linear", "aggressive"])
def test_memory_condition_predicts_the_target_and_a_scripted_user_succeeds(mode: str) -> None:
    protocol = load_protocol(MEMORY3)
    config = protocol.trial_config("memory", mode)
    result = run_trial(config, ScriptedInput(seed=1), seed=1)
    assert result.outcome == "success", result.outcome
    target = config.scene.object_names.index(config.scene.target)
    # Over the second half of the run the memory predictor names the user's goal, and by the
    # grasp it is confident: more than twice the other two together (the can, 19 cm from the
    # bottle, keeps some probability).
    late = result.records[len(result.records) // 2 :]
    assert all(r.predicted == target for r in late)
    assert max(r.probabilities[target] for r in late) > 2 / 3

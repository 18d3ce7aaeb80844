"""Live memory-based prediction with the user's rationality estimated online, logged per tick."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from app.teleop.scripted import ScriptedInput
from app.trial import records_from_samples, run_trial
from study.protocol import parse_protocol
from study.session.sample_writer import sample_row
from study.store import SAMPLE_COLUMNS

MEMORY3 = Path(__file__).resolve().parents[1] / "protocols" / "memory3.toml"


def _online_memory3() -> str:
    text = MEMORY3.read_text(encoding="utf-8")
    text, n = re.subn(r"(?m)^rationality = 30\.0$", 'rationality = "online"', text)
    assert n == 1, "memory3.toml's [prediction.memory] rationality moved: update this test"
    return text


def test_a_live_trial_predicts_with_an_online_rationality_and_logs_it(tmp_path) -> None:
    protocol = parse_protocol(_online_memory3(), path=tmp_path / "online.toml")
    assert protocol.prediction["memory"]["rationality"] == "online"
    config = protocol.config_for("memory", "linear", time_limit_s=30)
    result = run_trial(config, ScriptedInput(seed=2))
    assert result.success
    reaching = [r for r in result.records if math.isfinite(r.rationality)]
    assert len(reaching) > 20
    b = np.array([r.rationality for r in reaching])
    assert b.max() > 4 * b[0]  # moving at the target, the user is found rational toward it
    assert any(r.motion_agreement > 0.5 for r in reaching)

    # the samples row carries both, under their SAMPLE_COLUMNS names, and reads back
    rows = [sample_row(1, r.tick, r) for r in result.records]
    frame = {c: [row[i] for row in rows] for i, c in enumerate(SAMPLE_COLUMNS)}
    back = records_from_samples(pd.DataFrame(frame))
    i = result.records.index(reaching[-1])
    assert back[i].rationality == reaching[-1].rationality
    assert back[i].motion_agreement == reaching[-1].motion_agreement

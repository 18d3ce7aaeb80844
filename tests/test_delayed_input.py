"""Added latency as a level of a factor: the participant's commands act ``latency_s`` later,
in a headless trial and in a study session built from a protocol that declares it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from app.teleop.delayed_input import DelayedInput, delayed
from app.teleop.errors import TeleopError
from app.teleop.scripted import ScriptedInput
from app.teleop.types import TeleopCommand
from app.trial import Trial
from study.protocol import ProtocolValueError, parse_protocol

ROOT = Path(__file__).resolve().parents[1]
LAGGED = (
    (ROOT / "protocols" / "goals_mode.toml")
    .read_text()
    .replace(
        "[factors]\nmode",
        "[factors.lag]\nlevels.lag0 = { latency_s = 0.0 }\nlevels.lag300 = { latency_s = 0.3 }"
        "\n\n[factors]\nmode",
    )
    .replace("participants = 8 ", "participants = 16 ")
)


class _Counter:
    """Answers tick k with a target k cm along x and the gripper closed from tick 5."""

    def __init__(self) -> None:
        self.k = 0

    def command(self, obs: object) -> TeleopCommand:
        self.k += 1
        return TeleopCommand(np.array([0.01 * self.k, 0.0, 0.3]), self.k >= 5)


class _Obs:
    user_target = np.array([0.4, 0.0, 0.25])
    gripper_closed = False


def test_commands_come_through_the_given_number_of_ticks_late_and_the_robot_holds_till_then() -> (
    None
):
    source = DelayedInput(_Counter(), ticks=3)
    out = [source.command(_Obs()) for _ in range(8)]  # type: ignore[arg-type]
    for held in out[:3]:
        assert held.target.tolist() == [0.4, 0.0, 0.25] and held.grasp is False
    assert [round(c.target[0], 2) for c in out[3:]] == [0.01, 0.02, 0.03, 0.04, 0.05]
    assert [c.grasp for c in out[3:]] == [False, False, False, False, True]
    assert delayed(source, latency_s=0.004, rate_hz=100.0) is source  # under half a tick
    with pytest.raises(TeleopError, match="ticks"):
        DelayedInput(_Counter(), ticks=-1)


def _first_move_s(protocol_text: str, mode: str) -> float:
    """When the gripper has first moved 1 cm, in a trial of ``mode`` run as a session runs it."""
    protocol = parse_protocol(protocol_text)
    # unassisted, so that only the participant moves the gripper
    config = dataclasses.replace(protocol.trial_config("goals2", mode), arbitration=None)
    latency = float(config.extra.get("latency_s", 0.0))
    source = delayed(ScriptedInput(seed=1), latency_s=latency, rate_hz=config.rate_hz)
    trial = Trial(config, source, seed=1)
    start = None
    while not trial.done and trial.t < 3.0:
        trial.tick()
        ee = np.array(trial.sim.ee, dtype=float)
        start = ee if start is None else start
        if np.linalg.norm(ee - start) > 0.01:
            return trial.t
    raise AssertionError("the gripper never moved")


def test_a_latency_level_makes_the_gripper_answer_that_much_later() -> None:
    protocol = parse_protocol(LAGGED)
    assert protocol.factors["lag"] == ("lag0", "lag300")
    assert protocol.trial_config("goals2", "timid-lag0").extra["latency_s"] == 0.0
    assert (
        "latency_s"
        not in parse_protocol(
            LAGGED.replace("lag", "lg")
            .replace(
                "[factors.lg]\nlevels.lg0 = { latency_s = 0.0 }\nlevels.lg300 = { latency_s = 0.3 }\n\n",
                "",
            )
            .replace("participants = 16 ", "participants = 8 ")
        )
        .trial_config("goals2", "timid")
        .extra
    )
    prompt = _first_move_s(LAGGED, "timid-lag0")
    late = _first_move_s(LAGGED, "timid-lag300")
    assert late - prompt == pytest.approx(0.3, abs=0.03)


def test_a_latency_beyond_two_seconds_is_refused() -> None:
    text = LAGGED.replace("latency_s = 0.3", "latency_s = 5.0")
    with pytest.raises(ProtocolValueError) as info:
        parse_protocol(text)
    assert info.value.key == "factors.lag.levels.lag300.latency_s"

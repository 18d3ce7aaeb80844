"""Simulated-user models: a model defined here alone, named by a population file, is drawn and
simulated through the real session engine into a store."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from app.teleop import ScriptedInput
from app.trial import TrialConfig
from study.protocol import Answer, LikertItem
from study.session.answers import profile_answer
from study.session.screen import Screen
from study.session.trial_run import TrialSummary
from study.simulated import PopulationError, load_population, simulate
from study.simulated.models import UserModel, get_model, register, unregister
from study.simulated.population import participant_rng


@dataclass(frozen=True)
class StraightParams:
    speed_m_s: float  # how fast the hand moves the target
    rating: float  # the Likert answer to every rating item


@dataclass(frozen=True)
class StraightPeopleParams:
    index: int
    seed: int
    straight: StraightParams


class StraightPerson:
    """Straight to the target at a drawn speed (``ScriptedInput``); rates every run the same."""

    def __init__(self, params: StraightPeopleParams) -> None:
        self.params = params
        self.rng = participant_rng(params.index, seed=params.seed, stream=3)
        self.runs: list[TrialSummary] = []

    def __call__(self, config: TrialConfig, seed: int) -> ScriptedInput:
        return ScriptedInput(seed=seed, speed=self.params.straight.speed_m_s)

    def observe(self, summary: TrialSummary | None, *, time_limit_s: float) -> None:
        if summary is not None:
            self.runs.append(summary)

    def answer(self, screen: Screen) -> dict[str, Answer]:
        rating = round(self.params.straight.rating)
        return {
            item.id: rating if isinstance(item, LikertItem) else profile_answer(item, self.rng)
            for item in screen.items
        }


STRAIGHT = UserModel(
    name="straight",
    doc="straight to the target at a drawn speed; every run rated the same",
    sections={"straight": StraightParams},
    params=StraightPeopleParams,
    participant=StraightPerson,
)

POPULATION = """
[population]
doc = "People who go straight for the object."
model = "straight"

[straight]
speed_m_s = { dist = "uniform", low = 0.15, high = 0.2 }
rating = 5
"""


@pytest.fixture
def straight() -> Iterator[UserModel]:
    register(STRAIGHT)
    try:
        yield STRAIGHT
    finally:
        unregister("straight")


def test_a_model_defined_here_is_drawn_from_its_population_file(straight, tmp_path) -> None:
    path = tmp_path / "straight.toml"
    path.write_text(POPULATION, encoding="utf-8")
    population = load_population(path)
    assert population.model is straight
    params = population.draw(2, seed=7)
    assert params == population.draw(2, seed=7) and params.index == 2
    assert 0.15 <= params.straight.speed_m_s <= 0.2 and params.straight.rating == 5
    assert isinstance(population.model.participant(params), StraightPerson)


def test_a_model_defined_here_runs_simulated_participants(straight, tmp_path, short_protocol):
    path = tmp_path / "straight.toml"
    path.write_text(POPULATION, encoding="utf-8")
    db = tmp_path / "sim.db"
    report = simulate(
        protocol_path=short_protocol,
        db=db,
        participants=1,
        seed=4,
        population_path=path,
        progress=False,
    )
    assert report.errors == [] and report.participants == 1, report.as_dict()
    assert report.trials > 0 and report.outcomes == {"success": report.trials}
    assert report.ratings > 0


def test_an_unknown_model_is_named_with_the_known_ones(tmp_path) -> None:
    path = tmp_path / "nobody.toml"
    path.write_text(POPULATION.replace('"straight"', '"nobody"', 1), encoding="utf-8")
    with pytest.raises(PopulationError, match=r"population.model: 'nobody' is not .*interface"):
        load_population(path)


def test_the_default_model_is_the_interface_user() -> None:
    population = load_population()
    assert population.model is get_model("interface")
    assert np.isfinite(population.typical().motor.reaction_delay_s)

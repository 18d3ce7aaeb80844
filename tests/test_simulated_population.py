"""Population file, distributions and seeded per-participant draws."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from study.simulated import DEFAULT_POPULATION_PATH, Population, PopulationError, load_population
from study.simulated.distributions import Distribution


def population_dict() -> dict:
    return tomllib.loads(DEFAULT_POPULATION_PATH.read_text(encoding="utf-8"))


def test_default_population_file_loads_and_draws_plausible_people() -> None:
    pop = load_population()
    people = pop.draw_many(64, seed=1)
    delays = np.array([p.motor.reaction_delay_s for p in people])
    assert delays.min() >= 0.15 and delays.max() <= 0.8
    assert 0.2 < np.median(delays) < 0.4
    relaxers = sum(p.reaction.relaxer for p in people)
    assert 16 < relaxers < 48  # "some users relax": about half
    assert all(p.reaction.relaxer in (0.0, 1.0) for p in people)
    assert all(0.0 <= p.grasp.early_grasp_p <= 1.0 for p in people)
    assert len({p.questionnaire.rating_offset for p in people}) == 64


def test_participant_draw_depends_on_seed_and_index_only() -> None:
    pop = load_population()
    assert pop.draw(3, seed=9) == pop.draw_many(8, seed=9)[3]
    assert pop.draw(3, seed=9) == pop.draw_many(64, seed=9)[3]
    assert pop.draw(3, seed=9) != pop.draw(4, seed=9)
    assert pop.draw(3, seed=9) != pop.draw(3, seed=10)


def test_missing_parameter_is_named() -> None:
    data = population_dict()
    del data["motor"]["reaction_delay_s"]
    with pytest.raises(PopulationError, match=r"motor is missing reaction_delay_s"):
        Population.from_dict(data, source="pop.toml")


def test_unknown_parameter_is_named() -> None:
    data = population_dict()
    data["grasp"]["grasp_radius_cm"] = 2
    with pytest.raises(PopulationError, match=r"grasp\.grasp_radius_cm is not a parameter"):
        Population.from_dict(data, source="pop.toml")


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"dist": "gauss", "mean": 1}, r"motor\.noise_tau_s\.dist: expected one of"),
        ({"dist": "normal", "mean": 1}, r"normal distribution needs sd"),
        ({"dist": "lognormal", "median": -1, "sigma": 1}, r"median: must be > 0"),
        ({"dist": "bernoulli", "p": 1.5}, r"probability in \[0, 1\]"),
        ({"dist": "normal", "mean": 1, "sd": "big"}, r"sd: expected a number"),
        ({"dist": "uniform", "low": 2, "high": 1}, r"low 2.0 must not exceed high 1.0"),
        ("fast", r"expected a table"),
    ],
)
def test_bad_distribution_is_a_clear_error(table: object, message: str) -> None:
    data = population_dict()
    data["motor"]["noise_tau_s"] = table
    with pytest.raises(PopulationError, match=message):
        Population.from_dict(data, source="pop.toml")


def test_unreadable_and_invalid_files(tmp_path: Path) -> None:
    with pytest.raises(PopulationError, match="cannot read population file"):
        load_population(tmp_path / "absent.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[motor\n", encoding="utf-8")
    with pytest.raises(PopulationError, match="not valid TOML"):
        load_population(bad)


def test_distributions_sample_what_they_say() -> None:
    rng = np.random.default_rng(0)
    normal = Distribution.from_config(
        {"dist": "normal", "mean": 1.0, "sd": 0.5, "min": 0.5}, where="x"
    )
    xs = np.array([normal.sample(rng) for _ in range(4000)])
    assert xs.min() == 0.5
    logn = Distribution.from_config({"dist": "lognormal", "median": 2.0, "sigma": 0.3}, where="x")
    ys = np.array([logn.sample(rng) for _ in range(4000)])
    assert np.median(ys) == pytest.approx(2.0, rel=0.05)
    assert Distribution.from_config(0.25, where="x").sample(rng) == 0.25
    beta = Distribution.from_config({"dist": "beta", "a": 4, "b": 2}, where="x")
    assert beta.typical == pytest.approx(4 / 6)

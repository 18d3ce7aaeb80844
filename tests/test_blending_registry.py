"""The component registry: one declaration per kind, read by the builders, the loader and docs."""

from __future__ import annotations

import doctest
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import app.blending
from app.blending import (
    Arbitration,
    BuildContext,
    ConfigError,
    Kind,
    Param,
    StraightLinePolicy,
    arbitration_from_config,
    is_adversarial,
    register,
    unregister,
)
from app.blending.params import UNIT
from app.blending.spec import kinds, markdown
from app.teleop.scripted import ScriptedInput
from app.trial import run_trial
from study.protocol import parse_protocol
from study.protocol.errors import ProtocolValueError, UnknownKeyError

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"


class Smoothstep(Arbitration):
    """``alpha = alpha_max (3c^2 - 2c^3)``: a kind this test defines and registers."""

    def __init__(self, alpha_max: float) -> None:
        self.alpha_max = alpha_max
        self._validate()

    def __call__(self, c: float) -> float:
        return self.alpha_max * (3 * c * c - 2 * c * c * c)


SMOOTHSTEP = Kind(
    role="arbitration",
    name="smoothstep",
    doc="alpha = alpha_max (3c^2 - 2c^3)",
    params=(Param("alpha_max", UNIT, "alpha at c = 1", 0.8),),
    factory=lambda p, ctx: Smoothstep(p["alpha_max"]),
    example={"alpha_max": 0.8},
)


@pytest.fixture
def smoothstep() -> Iterator[Kind]:
    register(SMOOTHSTEP)
    try:
        yield SMOOTHSTEP
    finally:
        unregister("arbitration", "smoothstep")


def _with_mode(arbitration: str) -> str:
    text = PAPER.read_text(encoding="utf-8")
    text, n = re.subn(
        r'(?m)^arbitration = \{ kind = "aggressive".*$', f"arbitration = {arbitration}", text
    )
    assert n == 1, "dragan2013.toml's aggressive mode moved: update this test"
    return text


def test_a_kind_defined_here_runs_a_headless_trial_from_a_protocol(smoothstep, tmp_path) -> None:
    path = tmp_path / "smooth.toml"
    path.write_text(_with_mode('{ kind = "smoothstep", alpha_max = 0.7 }'), encoding="utf-8")
    protocol = parse_protocol(path.read_text(encoding="utf-8"), path=path)
    config = protocol.config_for("easy-right", "aggressive", time_limit_s=30)
    result = run_trial(config, ScriptedInput(seed=0))
    assert result.success
    reach = [r for r in result.records if r.alpha > 0]
    assert len(reach) > 10
    for r in reach:  # alpha is the new kind's curve of the logged confidence
        c = r.confidence
        assert r.alpha == pytest.approx(0.7 * (3 * c * c - 2 * c**3))


def test_the_loader_names_the_bad_key_and_lists_the_allowed_ones(smoothstep) -> None:
    with pytest.raises(UnknownKeyError) as info:
        parse_protocol(_with_mode('{ kind = "smoothstep", alpha_mx = 0.7 }'))
    assert info.value.key == "modes.aggressive.arbitration.alpha_mx"
    assert "allowed here: kind, alpha_max" in info.value.problem
    with pytest.raises(ProtocolValueError, match=r"alpha_max: must be in \[0, 1\], got 1.5"):
        parse_protocol(_with_mode('{ kind = "smoothstep", alpha_max = 1.5 }'))


def test_unregistered_kinds_are_rejected_with_the_registered_list() -> None:
    with pytest.raises(ProtocolValueError, match="'smoothstep' is not one of timid, aggressive"):
        parse_protocol(_with_mode('{ kind = "smoothstep" }'))


def test_every_registered_arbitration_must_be_monotone(smoothstep) -> None:
    register(
        Kind(
            "arbitration",
            "falling",
            "alpha = 1 - c (not allowed)",
            (),
            lambda p, ctx: _Falling(),
        ),
        replace=True,
    )
    try:
        with pytest.raises(ConfigError, match="must not decrease"):
            arbitration_from_config({"kind": "falling"}, where="modes.x")
    finally:
        unregister("arbitration", "falling")


class _Falling:
    """Not an Arbitration subclass: the registry checks it anyway."""

    def __call__(self, c: float) -> float:
        return 1.0 - c


def test_registering_twice_needs_replace(smoothstep) -> None:
    with pytest.raises(ConfigError, match="pass replace=True"):
        register(SMOOTHSTEP)


@pytest.mark.parametrize("name", list(kinds("arbitration")))
def test_every_registered_arbitration_is_monotone_and_never_adversarial(name: str) -> None:
    """Theorem 1 on each kind's example (stateful kinds in their initial state): from a state
    Q with the policy's P, some sampled user input always moves the robot."""
    kind = kinds("arbitration")[name]
    arb = arbitration_from_config({"kind": name, **kind.example}, where="x", rate_hz=50.0)
    cs = np.linspace(0, 1, 201)
    alphas = np.array([arb(c) for c in cs])
    assert ((alphas >= 0) & (alphas <= 1)).all() and (np.diff(alphas) >= -1e-12).all()
    rng = np.random.default_rng(0)
    q = np.zeros(3)
    p = StraightLinePolicy(0.05).step(q, np.array([1.0, 0.0, 0.0]))
    u = rng.normal(size=(64, 3)) * rng.uniform(0.01, 0.2, size=(64, 1))
    c = rng.uniform(0, 1, size=64)
    alpha = np.array([arb(x) for x in c])
    assert not is_adversarial(u, np.tile(p - q, (64, 1)), alpha)


def test_build_context_needs_are_enforced() -> None:
    with pytest.raises(ConfigError, match="'workspace_line' needs fk="):
        app.blending.policy_from_config({"kind": "workspace_line", "max_speed": 0.2}, rate_hz=50)
    assert BuildContext("x").rate_hz is None


def test_protocols_readme_lists_every_registered_kind_and_parameter() -> None:
    text = (ROOT / "protocols" / "README.md").read_text(encoding="utf-8")
    section = text.split("<!-- components:begin -->\n")[1].split("\n<!-- components:end -->")[0]
    for role in ("prediction", "confidence", "arbitration", "policy"):
        for kind in kinds(role).values():
            assert f"`{kind.name}`" in section
            for p in kind.params:
                if p.protocol:
                    assert f"`{p.name}`" in section
    assert section == markdown(), (
        "protocols/README.md's component table is out of date: paste the output of "
        "PYTHONPATH=. python -c 'import app.blending.spec as s, app.blending; print(s.markdown())'"
    )


def test_the_package_docstring_example_runs() -> None:
    result = doctest.testmod(app.blending, raise_on_error=False, verbose=False)
    assert result.attempted >= 5 and result.failed == 0

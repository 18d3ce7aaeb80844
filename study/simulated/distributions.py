"""Distributions of participant parameters, as written in a population file.

Each parameter of the population is one small table, e.g.
``reaction_delay_s = { dist = "lognormal", median = 0.25, sigma = 0.3 }``. Supported:

- ``fixed``      ``{value}``                       x = value
- ``normal``     ``{mean, sd, [min], [max]}``      x ~ N(mean, sd^2), clipped to [min, max]
- ``lognormal``  ``{median, sigma, [min], [max]}`` x = median * exp(sigma * z), z ~ N(0, 1)
- ``uniform``    ``{low, high}``                   x ~ U(low, high)
- ``beta``       ``{a, b}``                        x ~ Beta(a, b), in [0, 1]
- ``bernoulli``  ``{p}``                           x = 1 with probability p, else 0

Draws use the caller's ``numpy.random.Generator``; nothing here touches a global RNG.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from study.simulated.errors import PopulationError

_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # kind: (required keys, optional keys)
    "fixed": (("value",), ()),
    "normal": (("mean", "sd"), ("min", "max")),
    "lognormal": (("median", "sigma"), ("min", "max")),
    "uniform": (("low", "high"), ()),
    "beta": (("a", "b"), ()),
    "bernoulli": (("p",), ()),
}


@dataclass(frozen=True)
class Distribution:
    """One parameter's distribution: ``kind`` (see module docstring) and its numeric arguments."""

    kind: str
    args: Mapping[str, float]

    @classmethod
    def from_config(cls, table: Any, *, where: str) -> Distribution:
        """Parse ``{dist = ..., ...}`` (or a bare number, meaning ``fixed``); errors name ``where``."""
        if isinstance(table, bool):
            raise PopulationError(f"{where}: expected a number or a table, got a boolean")
        if isinstance(table, int | float):
            table = {"dist": "fixed", "value": table}
        if not isinstance(table, Mapping):
            raise PopulationError(
                f'{where}: expected a table like {{ dist = "normal", mean = 1, sd = 0.1 }},'
                f" got {type(table).__name__}"
            )
        kind = table.get("dist")
        if kind not in _KEYS:
            raise PopulationError(f"{where}.dist: expected one of {sorted(_KEYS)}, got {kind!r}")
        required, optional = _KEYS[kind]
        args: dict[str, float] = {}
        for key, value in table.items():
            if key in ("dist", "doc"):
                continue
            if key not in required and key not in optional:
                raise PopulationError(
                    f"{where}.{key}: not an argument of a {kind} distribution"
                    f" (allowed: {', '.join(required + optional)})"
                )
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise PopulationError(f"{where}.{key}: expected a number, got {value!r}")
            if not math.isfinite(value):
                raise PopulationError(f"{where}.{key}: expected a finite number, got {value!r}")
            args[key] = float(value)
        missing = [k for k in required if k not in args]
        if missing:
            raise PopulationError(f"{where}: a {kind} distribution needs {', '.join(missing)}")
        _check(kind, args, where=where)
        return cls(kind=kind, args=args)

    def sample(self, rng: np.random.Generator) -> float:
        """One draw."""
        a = self.args
        if self.kind == "fixed":
            return a["value"]
        if self.kind == "normal":
            x = a["mean"] + a["sd"] * rng.standard_normal()
        elif self.kind == "lognormal":
            x = a["median"] * math.exp(a["sigma"] * rng.standard_normal())
        elif self.kind == "uniform":
            return float(rng.uniform(a["low"], a["high"]))
        elif self.kind == "beta":
            return float(rng.beta(a["a"], a["b"]))
        else:  # bernoulli
            return float(rng.random() < a["p"])
        return float(min(max(x, a.get("min", -math.inf)), a.get("max", math.inf)))

    @property
    def typical(self) -> float:
        """The distribution's centre (mean, median or value): what a 'typical' participant has."""
        a = self.args
        return {
            "fixed": lambda: a["value"],
            "normal": lambda: min(max(a["mean"], a.get("min", -math.inf)), a.get("max", math.inf)),
            "lognormal": lambda: min(
                max(a["median"], a.get("min", -math.inf)), a.get("max", math.inf)
            ),
            "uniform": lambda: 0.5 * (a["low"] + a["high"]),
            "beta": lambda: a["a"] / (a["a"] + a["b"]),
            "bernoulli": lambda: a["p"],
        }[self.kind]()


def _check(kind: str, a: Mapping[str, float], *, where: str) -> None:
    if kind == "normal" and a["sd"] < 0:
        raise PopulationError(f"{where}.sd: must be >= 0, got {a['sd']}")
    if kind == "lognormal":
        if a["median"] <= 0:
            raise PopulationError(f"{where}.median: must be > 0, got {a['median']}")
        if a["sigma"] < 0:
            raise PopulationError(f"{where}.sigma: must be >= 0, got {a['sigma']}")
    if kind in ("normal", "lognormal") and a.get("min", -math.inf) > a.get("max", math.inf):
        raise PopulationError(f"{where}: min {a['min']} is above max {a['max']}")
    if kind == "uniform" and not a["low"] <= a["high"]:
        raise PopulationError(f"{where}: low {a['low']} must not exceed high {a['high']}")
    if kind == "beta" and (a["a"] <= 0 or a["b"] <= 0):
        raise PopulationError(f"{where}: beta needs a > 0 and b > 0, got a={a['a']}, b={a['b']}")
    if kind == "bernoulli" and not 0.0 <= a["p"] <= 1.0:
        raise PopulationError(f"{where}.p: a probability in [0, 1], got {a['p']}")

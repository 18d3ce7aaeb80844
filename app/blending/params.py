"""Parameter types of the component specifications (:mod:`app.blending.spec`).

Each type checks one table value (``check(value)`` returns it normalised, or raises
:class:`ParamProblem` with ``category`` ``type`` or ``value``) and describes itself for the docs
(``describe()``): a bounded :class:`Number`, an :class:`Integer`, a :class:`Choice` of strings
(optionally or a number), :class:`Pairs` of ``[c, alpha]``, prior :class:`Weights`, a goal by
:class:`IndexOrName`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from app.errors import AppError

__all__ = [
    "POSITIVE",
    "UNIT",
    "Choice",
    "IndexOrName",
    "Integer",
    "Number",
    "Pairs",
    "ParamProblem",
    "ParamType",
    "Weights",
    "type_name",
]


class ParamProblem(AppError):
    """A parameter value is wrong (``category`` ``type`` or ``value``); caught by :func:`check`."""

    def __init__(self, category: str, problem: str) -> None:
        super().__init__(problem)
        self.category = category
        self.problem = problem


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParamProblem("type", f"expected a number, got {type_name(value)} ({value!r})")
    v = float(value)
    if not math.isfinite(v):
        raise ParamProblem("value", f"must be finite, got {value!r}")
    return v


def type_name(value: object) -> str:
    for t, name in ((bool, "a boolean"), (int, "an integer"), (float, "a number")):
        if isinstance(value, t):
            return name
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a table"
    return "an array" if isinstance(value, list | tuple) else type(value).__name__


@dataclass(frozen=True)
class Number:
    """A finite number, optionally bounded (open or closed at either end)."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def check(self, value: Any) -> float:
        v = _number(value)
        lo_ok = self.lo is None or (v > self.lo if self.lo_open else v >= self.lo)
        hi_ok = self.hi is None or (v < self.hi if self.hi_open else v <= self.hi)
        if not (lo_ok and hi_ok):
            raise ParamProblem("value", f"must be {self.describe(bare=True)}, got {value!r}")
        return v

    def describe(self, *, bare: bool = False) -> str:
        if self.lo is not None and self.hi is not None:
            a, b = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            rng = f"in {a}{self.lo:g}, {self.hi:g}{b}"
        elif self.lo is not None:
            rng = f"{'>' if self.lo_open else '>='} {self.lo:g}"
        elif self.hi is not None:
            rng = f"{'<' if self.hi_open else '<='} {self.hi:g}"
        else:
            rng = "finite"
        return rng if bare else f"number {rng}"


POSITIVE = Number(0.0, lo_open=True)
UNIT = Number(0.0, 1.0)


@dataclass(frozen=True)
class Integer:
    """A whole number in ``[lo, hi]``."""

    lo: int
    hi: int

    def check(self, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParamProblem("type", f"expected an integer, got {type_name(value)} ({value!r})")
        if not self.lo <= value <= self.hi:
            raise ParamProblem("value", f"must be in [{self.lo}, {self.hi}], got {value!r}")
        return value

    def describe(self) -> str:
        return f"integer in [{self.lo}, {self.hi}]"


@dataclass(frozen=True)
class Choice:
    """One of a few strings, or (with ``number``) a number of that range instead."""

    choices: tuple[str, ...]
    number: Number | None = None

    def check(self, value: Any) -> Any:
        if self.number is not None and not isinstance(value, str):
            try:
                return self.number.check(value)
            except ParamProblem as p:
                raise ParamProblem(p.category, f"{p.problem}, or one of {self._list()}") from None
        if not isinstance(value, str):
            raise ParamProblem("type", f"expected a string, got {type_name(value)} ({value!r})")
        if value not in self.choices:
            raise ParamProblem("value", f"{value!r} is not one of {self._list()}")
        return value

    def _list(self) -> str:
        return ", ".join(repr(c) for c in self.choices)

    def describe(self) -> str:
        alt = f"{self.number.describe()} or " if self.number is not None else ""
        return alt + " \\| ".join(repr(c) for c in self.choices)


@dataclass(frozen=True)
class Pairs:
    """A non-empty list of ``[x, y]`` pairs, both in [0, 1] (e.g. ``[confidence, alpha]``)."""

    def check(self, value: Any) -> list[list[float]]:
        if not isinstance(value, list | tuple) or not value:
            raise ParamProblem("type", f"expected a non-empty array of pairs, got {value!r}")
        out = []
        for i, p in enumerate(value):
            if not isinstance(p, list | tuple) or len(p) != 2:
                raise ParamProblem("value", f"[{i}]: expected [confidence, alpha], got {p!r}")
            try:
                out.append([UNIT.check(p[0]), UNIT.check(p[1])])
            except ParamProblem as e:
                raise ParamProblem(e.category, f"[{i}]: {e.problem}") from None
        return out

    def describe(self) -> str:
        return "array of [c, alpha] pairs in [0, 1]"


@dataclass(frozen=True)
class Weights:
    """A non-empty list of numbers >= 0 with a positive sum (a prior, normalised later)."""

    def check(self, value: Any) -> list[float]:
        if not isinstance(value, list | tuple) or not value:
            raise ParamProblem("type", f"expected a non-empty array of numbers, got {value!r}")
        try:
            out = [Number(0.0).check(v) for v in value]
        except ParamProblem as e:
            raise ParamProblem(e.category, f"weights must be >= 0, got {list(value)!r}") from None
        if sum(out) <= 0:
            raise ParamProblem("value", "weights must be >= 0 with a positive sum")
        return out

    def describe(self) -> str:
        return "array of weights >= 0, one per goal"


@dataclass(frozen=True)
class IndexOrName:
    """A goal by index (an integer >= 0) or by name (a non-empty string)."""

    def check(self, value: Any) -> int | str:
        if isinstance(value, str) and value.strip():
            return value
        return Integer(0, 10**6).check(value)

    def describe(self) -> str:
        return "goal index or name"


ParamType = Number | Integer | Choice | Pairs | Weights | IndexOrName

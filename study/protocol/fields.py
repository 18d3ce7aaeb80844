"""Typed access to one TOML table, tracking the key path and catching unknown keys.

A :class:`Table` wraps a parsed TOML mapping. Each accessor checks the type (and optionally the
range) of one key and marks it as read; :meth:`Table.close` then rejects every key that was never
read, so a typo such as ``alpha_maz`` is an error instead of a silently ignored setting.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

from study.protocol.errors import (
    MissingKeyError,
    ProtocolTypeError,
    ProtocolValueError,
    UnknownKeyError,
)

T = TypeVar("T")
_MISSING: Any = object()


def _type_name(value: object) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return type(value).__name__


def join_key(prefix: str, name: str | int) -> str:
    """``join_key("tasks", "easy-right") == "tasks.easy-right"``; indices as ``items[2]``."""
    if isinstance(name, int):
        return f"{prefix}[{name}]"
    return f"{prefix}.{name}" if prefix else name


class Table:
    """One TOML table at ``key`` in ``file``; see the module docstring."""

    def __init__(self, data: Mapping[str, Any], *, file: Path | str, key: str = "") -> None:
        self.data = data
        self.file = file
        self.key = key
        self._read: set[str] = set()

    # -- bookkeeping -----------------------------------------------------------------------
    def where(self, name: str | int = "") -> str:
        return join_key(self.key, name) if name != "" else self.key

    def __contains__(self, name: str) -> bool:
        return name in self.data

    def keys(self) -> Iterator[str]:
        return iter(self.data)

    def close(self, *, allowed: str = "") -> None:
        """Raise :class:`UnknownKeyError` for the first key never read."""
        for name in self.data:
            if name not in self._read:
                hint = f" (allowed here: {allowed})" if allowed else ""
                raise UnknownKeyError(
                    f"unknown key {name!r}{hint}; check the spelling",
                    file=self.file,
                    key=self.where(name),
                )

    def only(self, *allowed: str) -> None:
        """Reject keys outside ``allowed`` up front, so a typo is reported as itself rather
        than as the required key it misspells."""
        for name in self.data:
            if name not in allowed:
                raise UnknownKeyError(
                    f"unknown key {name!r} (allowed here: {', '.join(allowed)}); check the"
                    " spelling",
                    file=self.file,
                    key=self.where(name),
                )

    def _get(self, name: str, default: Any) -> Any:
        self._read.add(name)
        if name in self.data:
            return self.data[name]
        if default is _MISSING:
            raise MissingKeyError("required key is missing", file=self.file, key=self.where(name))
        return default

    def _type_error(self, name: str | int, value: object, expected: str) -> ProtocolTypeError:
        return ProtocolTypeError(
            f"expected {expected}, got {_type_name(value)} ({value!r})",
            file=self.file,
            key=self.where(name),
        )

    def value_error(self, name: str | int, problem: str) -> ProtocolValueError:
        return ProtocolValueError(problem, file=self.file, key=self.where(name))

    # -- typed accessors -------------------------------------------------------------------
    def string(self, name: str, default: Any = _MISSING, *, nonempty: bool = True) -> str:
        value = self._get(name, default)
        if not isinstance(value, str):
            raise self._type_error(name, value, "a string")
        if nonempty and not value.strip():
            raise self.value_error(name, "must not be empty")
        return value

    def choice(self, name: str, choices: tuple[str, ...], default: Any = _MISSING) -> str:
        value = self.string(name, default)
        if value not in choices:
            raise self.value_error(name, f"{value!r} is not one of {', '.join(choices)}")
        return value

    def integer(
        self,
        name: str,
        default: Any = _MISSING,
        *,
        minimum: int | None = None,
        maximum: int | None = None,
    ) -> int:
        value = self._get(name, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self._type_error(name, value, "an integer")
        _check_range(self, name, value, minimum, maximum)
        return value

    def number(
        self,
        name: str,
        default: Any = _MISSING,
        *,
        minimum: float | None = None,
        maximum: float | None = None,
        positive: bool = False,
    ) -> float:
        value = self._get(name, default)
        return check_number(self, name, value, minimum=minimum, maximum=maximum, positive=positive)

    def boolean(self, name: str, default: Any = _MISSING) -> bool:
        value = self._get(name, default)
        if not isinstance(value, bool):
            raise self._type_error(name, value, "true or false")
        return value

    def array(self, name: str, default: Any = _MISSING, *, nonempty: bool = True) -> list[Any]:
        value = self._get(name, default)
        if not isinstance(value, list):
            raise self._type_error(name, value, "an array")
        if nonempty and not value:
            raise self.value_error(name, "must not be empty")
        return value

    def strings(
        self, name: str, default: Any = _MISSING, *, nonempty: bool = True, unique: bool = True
    ) -> tuple[str, ...]:
        values = self.array(name, default, nonempty=nonempty)
        for i, v in enumerate(values):
            if not isinstance(v, str) or not v.strip():
                raise ProtocolTypeError(
                    f"expected a non-empty string, got {_type_name(v)} ({v!r})",
                    file=self.file,
                    key=join_key(self.where(name), i),
                )
        if unique:
            seen: set[str] = set()
            for v in values:
                if v in seen:
                    raise self.value_error(name, f"{v!r} is listed twice")
                seen.add(v)
        return tuple(values)

    def table(self, name: str, default: Any = _MISSING) -> Table:
        value = self._get(name, default)
        if not isinstance(value, Mapping):
            raise self._type_error(name, value, "a table")
        return Table(value, file=self.file, key=self.where(name))

    def raw(self, name: str, default: Any = _MISSING) -> Any:
        return self._get(name, default)

    def tables(self) -> Iterator[tuple[str, Table]]:
        """Every key of this table, each of which must itself be a table (``[tasks.*]``)."""
        for name in self.data:
            yield name, self.table(name)


def check_number(
    table: Table,
    name: str | int,
    value: object,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
) -> float:
    """``value`` as a finite float in range, else a typed error at ``table.where(name)``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise table._type_error(name, value, "a number")
    number = float(value)
    if not math.isfinite(number):
        raise table.value_error(name, f"must be finite, got {value!r}")
    if positive and number <= 0:
        raise table.value_error(name, f"must be > 0, got {value!r}")
    _check_range(table, name, number, minimum, maximum)
    return number


def _check_range(
    table: Table, name: str | int, value: float, minimum: float | None, maximum: float | None
) -> None:
    if minimum is not None and value < minimum:
        raise table.value_error(name, f"must be >= {minimum}, got {value!r}")
    if maximum is not None and value > maximum:
        raise table.value_error(name, f"must be <= {maximum}, got {value!r}")


def each(table: Table, name: str, items: list[Any], parse: Callable[[Table], T]) -> list[T]:
    """Parse every element of the array ``name`` (each must be an inline table)."""
    out: list[T] = []
    for i, item in enumerate(items):
        if not isinstance(item, Mapping):
            raise table._type_error(f"{name}[{i}]", item, "a table")
        sub = Table(item, file=table.file, key=join_key(table.where(name), i))
        out.append(parse(sub))
    return out

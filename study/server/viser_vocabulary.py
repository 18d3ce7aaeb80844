"""viser's own fixed vocabulary: the values its message fields may take (``Literal`` types).

A protocol level can be an ordinary word that viser also uses as a setting ("standard" is both
a level of ``protocols/memory3.toml`` and the default ``material`` of every mesh viser sends).
Such a value is the same in every condition, so it reveals nothing; the blinding guard lets a
string through when it is exactly one of the values viser declares for the field it sits in,
and checks everything else. The table is read from viser's message classes
(:func:`study.server.viser_door.message_classes`) when this module is imported (viser is pinned
to the tested minor version).
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from study.server import viser_door


def _literals(tp: Any, out: set[str], seen: set[type], fields: dict[str, set[str]]) -> None:
    """Collect the string ``Literal`` values inside type ``tp`` into ``out``; recurse into
    nested dataclasses (their fields land in ``fields``)."""
    if typing.get_origin(tp) is typing.Literal:
        out.update(a for a in typing.get_args(tp) if isinstance(a, str))
        return
    for arg in typing.get_args(tp):
        _literals(arg, out, seen, fields)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type) and tp not in seen:
        seen.add(tp)
        for name, hint in typing.get_type_hints(tp).items():
            values: set[str] = set()
            _literals(hint, values, seen, fields)
            if values:
                fields.setdefault(name, set()).update(values)


def _field_values() -> Mapping[str, frozenset[str]]:
    fields: dict[str, set[str]] = {}
    seen: set[type] = set()
    for cls in viser_door.message_classes():
        _literals(cls, set(), seen, fields)
    return MappingProxyType({k: frozenset(v) for k, v in fields.items()})


FIELD_VALUES: Mapping[str, frozenset[str]] = _field_values()
"""Field name -> the fixed string values viser declares for it (e.g. ``material`` ->
``standard``, ``toon3``, ``toon5``), over every message class and its nested props."""


def is_viser_setting(field: str, value: str) -> bool:
    """True when ``value`` is one of the fixed values viser declares for ``field``."""
    return value in FIELD_VALUES.get(field, ())

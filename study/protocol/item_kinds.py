"""Questionnaire item kinds: one declaration per kind, read by the protocol loader.

An :class:`ItemKind` names a ``type`` a protocol's ``[questionnaire.items.<id>]`` table may give,
the keys its table takes besides ``type`` and ``prompt``, and its reader, which builds the item
from the table (``read(item_id, prompt, table, scales)``, the table's keys already checked). The
item it builds is a frozen dataclass with ``id``, ``prompt``, ``optional``, a class-level
``kind`` (the name), ``texts()`` (what a participant reads: checked for condition words) and
``check(value)`` (the answer normalised, or :class:`~study.protocol.errors.AnswerError`), like
the built-in kinds of :mod:`study.protocol.questionnaire`. Optionally ``sample(rng)``: a seeded
answer for simulated participants (``study.session.answers.profile_answer``); the page shows
any kind it has no field of its own for as a text field checked by ``check``.

A kind other than ``likert`` is asked once per participant (``before_training``,
``between_tasks``, ``closing``). A new kind is one class and one :func:`register_item_kind`
call; the built-in kinds are registered by :mod:`study.protocol.items`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from study.protocol.errors import ProtocolError

if TYPE_CHECKING:
    from study.protocol.fields import Table
    from study.protocol.questionnaire import Scale

__all__ = ["ItemKind", "item_kind", "item_kinds", "register_item_kind", "unregister_item_kind"]

ItemReader = Callable[[str, str, "Table", Mapping[str, "Scale"]], Any]
"""``read(item_id, prompt, table, scales) -> item``."""


@dataclass(frozen=True)
class ItemKind:
    """A questionnaire item kind (module docstring): ``name`` (the protocol's ``type``), the
    ``keys`` its table takes besides ``type`` and ``prompt``, and its ``read``er."""

    name: str
    keys: tuple[str, ...]
    read: ItemReader
    doc: str = ""


_REGISTRY: dict[str, ItemKind] = {}


def register_item_kind(kind: ItemKind, *, replace: bool = False) -> ItemKind:
    """Add ``kind`` (``replace=True`` to redefine an existing name)."""
    if not kind.name or not kind.name.replace("_", "").isalnum() or not kind.name.islower():
        raise _refused(kind, "use lower-case letters, digits and '_' for its name")
    if kind.name in _REGISTRY and not replace:
        raise _refused(kind, "exists; pass replace=True to redefine it")
    if {"type", "prompt"} & set(kind.keys):
        raise _refused(kind, "'type' and 'prompt' are every kind's keys; list only its own")
    _REGISTRY[kind.name] = kind
    return kind


def _refused(kind: ItemKind, problem: str) -> ProtocolError:
    return ProtocolError(
        f"item kind {kind.name!r}: {problem}", file="<item kinds>", key="questionnaire.items"
    )


def unregister_item_kind(name: str) -> None:
    """Remove a kind (tests that register their own)."""
    _REGISTRY.pop(name, None)


def item_kinds() -> dict[str, ItemKind]:
    """The registered kinds, by name (in registration order: the built-in ones first)."""
    return _REGISTRY


def item_kind(name: str) -> ItemKind:
    return _REGISTRY[name]

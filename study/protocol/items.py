"""``[questionnaire]``: scales, items of every kind, and the moments they are asked.

    [questionnaire]
    points = 7                                   # Likert scales' length
    before_training = ["age_band", "gender"]     # after consent
    after_training = ["helpful"]                 # run moments: Likert items only
    after_run = ["helpful"]
    after_task = ["preference"]
    between_tasks = [{ after_task = 2, items = ["attention"] }]
    closing = ["comment", "keep_data"]           # before the debrief

    [questionnaire.items.age_band]               # type: likert (default), choice,
    type = "choice"                              # attention, retention, number, text
    prompt = "How old are you?"
    options = ["18-24", "25-34", "35 or older", "Prefer not to say"]

Per kind: ``likert`` takes ``scale``; ``choice`` ``options``; ``attention`` also ``correct``
(one of the options); ``retention`` also ``keep`` (the option that agrees to keeping the
data; asked in ``closing``, at most one such item); ``number`` ``minimum``, ``maximum``,
``unit`` and ``whole`` (default true); ``text`` ``max_length`` (default 1000). Every kind but
Likert takes ``optional`` (default false, true for text). An item asked once per participant
(any kind but Likert) may appear in one moment only. Each kind is one registered
:class:`~study.protocol.item_kinds.ItemKind` (its keys and its reader): the built-in ones are
registered here, a new one by :func:`~study.protocol.item_kinds.register_item_kind`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from types import MappingProxyType

from study.protocol.errors import ScaleMismatchError, UndefinedReferenceError
from study.protocol.fields import Table, each, join_key
from study.protocol.item_kinds import ItemKind, item_kind, item_kinds, register_item_kind
from study.protocol.questionnaire import (
    ONCE_PHASES,
    RUN_PHASES,
    AttentionItem,
    ChoiceItem,
    Item,
    LikertItem,
    NumberItem,
    Questionnaire,
    RetentionItem,
    Scale,
    TextItem,
)

_ITEM_ID = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
MAX_OPTIONS = 20
MAX_TEXT_LENGTH = 2000
"""Longest free-text answer a protocol may allow (the page sends it in one message)."""
DEFAULT_TEXT_LENGTH = 1000


def read_questionnaire(t: Table, *, n_modes: int, n_tasks: int) -> Questionnaire:
    """``[questionnaire]`` (module docstring); typed errors name the key that is wrong."""
    t.only("points", "scales", "items", *RUN_PHASES, *ONCE_PHASES)
    points = t.integer("points", minimum=2, maximum=11)
    scales = _scales(t, points)
    items: dict[str, Item] = {}
    items_table = t.table("items")
    for item_id, sub in items_table.tables():
        if not _ITEM_ID.match(item_id):
            raise items_table.value_error(
                item_id, "item ids name data columns: lower-case letters, digits and '_'"
            )
        items[item_id] = _item(item_id, sub, scales)
    run = {phase: _asked(t, phase, items) for phase in RUN_PHASES}
    for phase, asked in run.items():
        for i, item in enumerate(asked):
            if not isinstance(item, LikertItem):
                raise t.value_error(
                    join_key(phase, i),
                    f"item {item.id!r} is a {item.kind} item; {phase} holds rating-scale"
                    " (likert) items only: ask it before_training, between_tasks or closing",
                )
    if run["after_task"] and n_modes != 2:
        raise t.value_error(
            "after_task",
            f"a preference between a task's two runs needs exactly 2 modes, this protocol has"
            f" {n_modes}; leave after_task empty",
        )
    before = _asked(t, "before_training", items)
    between = _between(t, items, n_tasks) if "between_tasks" in t else ()
    closing = _asked(t, "closing", items)
    _check_once(t, before, between, closing)
    return Questionnaire(
        points=points,
        items=MappingProxyType(items),
        after_training=run["after_training"],  # type: ignore[arg-type]
        after_run=run["after_run"],  # type: ignore[arg-type]
        after_task=run["after_task"],  # type: ignore[arg-type]
        before_training=before,
        between_tasks=between,
        closing=closing,
    )


def _scales(t: Table, points: int) -> dict[str, Scale]:
    scales: dict[str, Scale] = {}
    for name, sub in t.table("scales", {}).tables():
        sub.only("anchors")
        anchors = sub.strings("anchors", unique=True)
        if len(anchors) != points:
            raise ScaleMismatchError(
                f"{len(anchors)} anchors for a {points}-point questionnaire"
                f" (questionnaire.points = {points}); give one anchor per point",
                file=t.file,
                key=sub.where("anchors"),
            )
        scales[name] = Scale(name=name, anchors=anchors)
    return scales


def _item(item_id: str, sub: Table, scales: dict[str, Scale]) -> Item:
    kind = item_kind(sub.choice("type", tuple(item_kinds()), "likert"))
    sub.only("type", "prompt", *kind.keys)
    item: Item = kind.read(item_id, sub.string("prompt"), sub, scales)
    return item


def _likert(item_id: str, prompt: str, sub: Table, scales: Mapping[str, Scale]) -> LikertItem:
    scale_name = sub.string("scale")
    if scale_name not in scales:
        raise UndefinedReferenceError(
            f"scale {scale_name!r} is not defined in questionnaire.scales"
            f" ({', '.join(scales) or 'none'})",
            file=sub.file,
            key=sub.where("scale"),
        )
    return LikertItem(id=item_id, prompt=prompt, scale=scales[scale_name])


def _number(item_id: str, prompt: str, sub: Table, scales: Mapping[str, Scale]) -> NumberItem:
    low = sub.number("minimum")
    high = sub.number("maximum")
    whole = sub.boolean("whole", True)
    if high <= low:
        raise sub.value_error("maximum", f"must be above minimum ({low:g}), got {high:g}")
    if whole and (low != int(low) or high != int(high)):
        raise sub.value_error("minimum", "a whole-number item needs whole-number bounds")
    return NumberItem(
        id=item_id,
        prompt=prompt,
        minimum=low,
        maximum=high,
        unit=sub.string("unit", "", nonempty=False).strip(),
        whole=whole,
        optional=sub.boolean("optional", False),
    )


def _text(item_id: str, prompt: str, sub: Table, scales: Mapping[str, Scale]) -> TextItem:
    return TextItem(
        id=item_id,
        prompt=prompt,
        max_length=sub.integer(
            "max_length", DEFAULT_TEXT_LENGTH, minimum=1, maximum=MAX_TEXT_LENGTH
        ),
        optional=sub.boolean("optional", True),
    )


def _options(sub: Table) -> tuple[tuple[str, ...], bool]:
    """A choice's ``options`` (2 to ``MAX_OPTIONS``, unique) and ``optional``."""
    options = sub.strings("options", unique=True)
    if not 2 <= len(options) <= MAX_OPTIONS:
        raise sub.value_error("options", f"give 2 to {MAX_OPTIONS} options, got {len(options)}")
    return options, sub.boolean("optional", False)


def _marked(sub: Table, key: str, options: tuple[str, ...]) -> str:
    """The option ``key`` marks (``correct``, ``keep``): one of ``options``."""
    marked = sub.string(key)
    if marked not in options:
        raise sub.value_error(key, f"{marked!r} is not one of the item's options")
    return marked


def _choice(item_id: str, prompt: str, sub: Table, scales: Mapping[str, Scale]) -> ChoiceItem:
    options, optional = _options(sub)
    return ChoiceItem(id=item_id, prompt=prompt, options=options, optional=optional)


def _attention(item_id: str, prompt: str, sub: Table, scales: Mapping[str, Scale]) -> AttentionItem:
    options, optional = _options(sub)
    correct = _marked(sub, "correct", options)
    return AttentionItem(
        id=item_id, prompt=prompt, options=options, optional=optional, correct=correct
    )


def _retention(item_id: str, prompt: str, sub: Table, scales: Mapping[str, Scale]) -> RetentionItem:
    options, optional = _options(sub)
    keep = _marked(sub, "keep", options)
    return RetentionItem(id=item_id, prompt=prompt, options=options, optional=optional, keep=keep)


for _kind in (
    ItemKind("likert", ("scale",), _likert, "a rating on a named scale (the default)"),
    ItemKind("choice", ("options", "optional"), _choice, "one of the options"),
    ItemKind("attention", ("options", "optional", "correct"), _attention, "an attention check"),
    ItemKind("retention", ("options", "optional", "keep"), _retention, "keep the data?"),
    ItemKind("number", ("minimum", "maximum", "unit", "whole", "optional"), _number, "a number"),
    ItemKind("text", ("max_length", "optional"), _text, "free text"),
):
    register_item_kind(_kind)


def _asked(t: Table, phase: str, items: dict[str, Item], *, key: str = "") -> tuple[Item, ...]:
    """The items listed under ``phase`` (``key``: the array's own key when nested)."""
    ids = t.strings(key or phase, [], nonempty=False)
    for i, item_id in enumerate(ids):
        if item_id not in items:
            raise UndefinedReferenceError(
                f"item {item_id!r} is not defined in questionnaire.items",
                file=t.file,
                key=join_key(t.where(key or phase), i),
            )
    return tuple(items[i] for i in ids)


def _between(
    t: Table, items: dict[str, Item], n_tasks: int
) -> tuple[tuple[int, tuple[Item, ...]], ...]:
    """``between_tasks = [{ after_task = k, items = [...] }, ...]``, k in ``1..n_tasks - 1``."""

    def page(sub: Table) -> tuple[int, tuple[Item, ...]]:
        sub.only("after_task", "items")
        k = sub.integer("after_task", minimum=1)
        if k >= n_tasks:
            raise sub.value_error(
                "after_task",
                f"{k} is not between two of the {n_tasks} tasks (1..{n_tasks - 1}); after the"
                " last task, use closing",
            )
        asked = _asked(sub, "items", items)
        if not asked:
            raise sub.value_error("items", "must not be empty")
        return k, asked

    pages = each(t, "between_tasks", t.array("between_tasks", nonempty=False), page)
    seen: set[int] = set()
    for i, (k, _) in enumerate(pages):
        if k in seen:
            raise t.value_error(
                join_key("between_tasks", i), f"two pages after task {k}; merge them"
            )
        seen.add(k)
    return tuple(sorted(pages))


def _check_once(
    t: Table,
    before: tuple[Item, ...],
    between: tuple[tuple[int, tuple[Item, ...]], ...],
    closing: tuple[Item, ...],
) -> None:
    """An item answered once per participant is asked in one moment only; the retention
    question comes at the end (closing), at most once."""
    where: dict[str, str] = {}
    pages = [("before_training", before), *(("between_tasks", p) for _, p in between)]
    for phase, asked in [*pages, ("closing", closing)]:
        for item in asked:
            if isinstance(item, LikertItem):
                continue
            if item.id in where:
                raise t.value_error(
                    phase,
                    f"item {item.id!r} is already asked in {where[item.id]}; a participant"
                    " answers it once",
                )
            where[item.id] = phase
            if isinstance(item, RetentionItem) and phase != "closing":
                raise t.value_error(
                    phase,
                    f"the data-retention item {item.id!r} belongs at the end of the study:"
                    " list it in closing",
                )
    retention = [i for i in closing if isinstance(i, RetentionItem)]
    if len(retention) > 1:
        raise t.value_error(
            "closing", f"one data-retention item at most, got {[i.id for i in retention]}"
        )


__all__ = ["read_questionnaire"]

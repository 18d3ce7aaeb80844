"""The participant page's fields for questionnaire items.

:meth:`study.server.participant_page.ParticipantPage.show_questions` draws each item's prompt
and its field here, one field per item under its prompt:

- Likert items: a row of buttons 1..points (the chosen one relabelled ``[k]``, drawn filled by
  the page script) and a line that says the answer with its anchor;
- choice, attention and retention items: a dropdown whose first entry, :data:`CHOOSE`, means
  "not answered yet" (no option is preselected: a default would be an answer nobody gave);
- number items: a text field (empty until typed: a number input would start at some value),
  checked on every change against the item's range; the line under it says what it accepts or
  echoes the number read (digits only);
- free text: a multi-line field with a character count under it. The text itself is never
  sent back to the page: it is data, and the page must not receive condition words, which a
  participant may well type. (viser queues an echo of each typed value for the typing tab's
  own connection, which never sends it: the blinding guard drops such echoes unread,
  ``study.server.blinding_guard``.)

Each field reports ``(item id, value or None, valid)`` through ``report``; the page enables
Continue once every required item has a valid answer and nothing typed is invalid. The
server checks every answer again (``Session.answer``): what a field accepts, it accepts.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Protocol

import viser

from study.protocol import AnswerError, ChoiceItem, Item, LikertItem, NumberItem, TextItem
from study.server.blinding_guard import check_text
from study.server.page_inputs import InputRejected, parse_answer


class FieldPage(Protocol):
    """What a field needs of the page it is drawn on (``ParticipantPage`` has it): the tab's
    client, the blinded words its texts are checked against, a markdown line, the list of
    handles the page removes with the screen, and a way to reject an answer with a notice."""

    client: viser.ClientHandle
    words: tuple[str, ...]
    _handles: list[object]

    def _md(self, text: str) -> viser.GuiMarkdownHandle: ...

    def reject(self, problem: str, notify: bool = True) -> None: ...


CHOOSE = "(choose an answer)"
"""The dropdown's first entry: no answer chosen yet."""

Report = Callable[[str, object, bool], None]
"""``report(item_id, value, valid)``: a field's current value (``None``: empty)."""


def add_answer_field(
    page: FieldPage, item: Item, *, current: Callable[[], bool], report: Report
) -> None:
    """Draw ``item``'s field on ``page`` (its prompt is drawn already); ``current()`` says the
    screen is still shown (a late update from an old screen is ignored)."""
    if isinstance(item, LikertItem):
        _likert(page, item, current=current, report=report)
    elif isinstance(item, ChoiceItem):
        _choice(page, item, current=current, report=report)
    elif isinstance(item, NumberItem):
        _number(page, item, current=current, report=report)
    elif isinstance(item, TextItem):
        _text(page, item, current=current, report=report)
    else:  # a registered kind (study.protocol.item_kinds): typed, checked by the item itself
        _typed(page, item, current=current, report=report)


def _likert(
    page: FieldPage, item: LikertItem, *, current: Callable[[], bool], report: Report
) -> None:
    """A row of buttons 1..points; the chosen one reads ``[k]`` and the line under the row
    says the answer with its anchor."""
    plain = tuple(str(k) for k in range(1, item.points + 1))
    group = page.client.gui.add_button_group(" ", plain)
    page._handles.append(group)
    chosen = page._md("Your answer: none yet")

    def on_click(_: object) -> None:
        if not current():
            return
        try:
            answer = parse_answer(str(group.value).strip("[] "), points=item.points)
        except InputRejected as exc:
            page.reject(str(exc))
            return
        marked = [f"[{o}]" if int(o) == answer else o for o in plain]
        group.options = tuple(marked)  # the chosen button reads [k]
        chosen.content = f"Your answer: **{answer}** ({item.anchors[answer - 1]})"
        report(item.id, answer, True)

    group.on_click(on_click)


def _choice(
    page: FieldPage, item: ChoiceItem, *, current: Callable[[], bool], report: Report
) -> None:
    options = (CHOOSE, *item.options)
    field = page.client.gui.add_dropdown(
        "Answer", tuple(check_text(o, words=page.words) for o in options), initial_value=CHOOSE
    )
    page._handles.append(field)
    if item.optional:
        page._md("_You may leave this one unanswered._")

    @field.on_update
    async def _(_: object) -> None:
        if not current():
            return
        value = str(field.value)
        if value == CHOOSE:
            report(item.id, None, True)
            return
        try:
            report(item.id, item.check(value), True)
        except AnswerError:  # not one of the options: a forged message
            problem = f"item {item.id}: not one of its options"
            asyncio.get_running_loop().run_in_executor(None, page.reject, problem, False)
            report(item.id, None, False)


def _number(
    page: FieldPage, item: NumberItem, *, current: Callable[[], bool], report: Report
) -> None:
    accepts = f"Please enter {item.range_text()}."
    # no hint: viser shows it as a tooltip over the prompt, and the line under the field
    # says the same (the tooltip and the line said it twice)
    field = page.client.gui.add_text(
        check_text(item.unit or "Number", words=page.words), initial_value=""
    )
    page._handles.append(field)
    note = page._md(accepts + (" You may leave it empty." if item.optional else ""))

    @field.on_update
    async def _(_: object) -> None:
        if not current():
            return
        typed = str(field.value)
        try:
            value = item.check(typed)
        except AnswerError:
            note.content = check_text(f"**{accepts}**", words=page.words)
            report(item.id, None, False)
            return
        if value is None:
            note.content = check_text(accepts, words=page.words)
        else:
            unit = f" {item.unit}" if item.unit else ""
            note.content = check_text(f"Your answer: {value:g}{unit}", words=page.words)
        report(item.id, value, True)


def _text(page: FieldPage, item: TextItem, *, current: Callable[[], bool], report: Report) -> None:
    limit = f"at most {item.max_length} characters"
    field = page.client.gui.add_text("Answer", initial_value="", multiline=True)  # no tooltip
    page._handles.append(field)
    empty = " You may leave it empty." if item.optional else ""
    count = page._md(f"0 of {item.max_length} characters.{empty}")

    @field.on_update
    async def _(_: object) -> None:
        if not current():
            return
        typed = str(field.value)
        try:
            value = item.check(typed)
        except AnswerError:  # too long (or required and empty): say so, never echo the text
            n = len(typed.strip())
            if n > item.max_length:
                count.content = f"**{n} of {item.max_length} characters: please shorten it.**"
            else:
                count.content = f"Please write an answer ({limit})."
            report(item.id, None, False)
            return
        count.content = f"{len(value or '')} of {item.max_length} characters.{empty}"
        report(item.id, value, True)


__all__ = ["CHOOSE", "add_answer_field"]


def _typed(page: FieldPage, item: Item, *, current: Callable[[], bool], report: Report) -> None:
    """Any other kind: a one-line text field whose every change the item's ``check`` reads
    (what it refuses is marked, never echoed)."""
    field = page.client.gui.add_text("Answer", initial_value="")
    page._handles.append(field)
    note = page._md("You may leave it empty." if getattr(item, "optional", False) else "")

    @field.on_update
    async def _(_: object) -> None:
        if not current():
            return
        try:
            value = item.check(str(field.value))
        except AnswerError:
            note.content = "**Please check your answer.**"
            report(item.id, None, False)
            return
        note.content = ""
        report(item.id, value, True)

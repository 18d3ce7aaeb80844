"""Questionnaire items, their answers, and when they are asked.

Item kinds (``type`` in the protocol; each checks its own answers with ``check``):

- :class:`LikertItem` (``likert``, the default): a prompt on a :class:`Scale`; answer 1..points.
- :class:`ChoiceItem` (``choice``): one of a list of options, answered with the option's text.
- :class:`AttentionItem` (``attention``): a choice with a declared ``correct`` option; a wrong
  answer is recorded as given and counted as a failed check (export, report).
- :class:`RetentionItem` (``retention``): a choice whose ``keep`` option agrees that the
  participant's data are kept; any other answer excludes them from export and analysis.
- :class:`NumberItem` (``number``): a number within ``minimum..maximum`` (whole numbers only if
  ``whole``), with an optional ``unit`` shown beside the field.
- :class:`TextItem` (``text``): free text of at most ``max_length`` characters.

Each kind is registered with its reader in :mod:`study.protocol.item_kinds` (the built-in ones
by :mod:`study.protocol.items`); a new kind is one class like these and one registration.

Every kind but Likert may be ``optional``: an empty answer is then recorded as "left empty"
(``None``). A refused answer raises :class:`AnswerError` naming the item and what it accepts,
never quoting what was typed: a participant's text is data, and an error message may reach
their page (whose every string is checked for condition words).

The :class:`Questionnaire` says which items are asked when: ``before_training`` (after consent:
demographics), ``after_training`` (ratings of the unassisted robot, the baseline covariate),
``after_run`` (one rating per condition), ``after_task`` (the preference between a task's two
runs: 1 = strongly preferred the first run, ``points`` = the second), ``between_tasks`` (after
task k of the schedule, e.g. an attention check halfway) and ``closing`` (after the last run,
before the debrief: a comment, the retention question). The three run phases hold Likert
items only; the other three, asked once per participant, hold any kind.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from study.protocol.errors import AnswerError

RUN_PHASES = ("after_training", "after_run", "after_task")
"""Questionnaire moments tied to runs: rating-scale (Likert) items only."""
ONCE_PHASES = ("before_training", "between_tasks", "closing")
"""Questionnaire moments asked once per participant: items of any kind."""
PHASES = ("before_training", *RUN_PHASES, "between_tasks", "closing")
MAX_NUMBER_CHARS = 32
"""Longest text accepted as a number answer (digits, sign, one decimal mark)."""
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


@dataclass(frozen=True)
class Scale:
    """An ordered response scale; answer ``k`` (1-based) means ``anchors[k - 1]``."""

    name: str
    anchors: tuple[str, ...]

    @property
    def points(self) -> int:
        return len(self.anchors)

    @property
    def midpoint(self) -> float:
        """The neutral answer, ``(points + 1) / 2`` (4 on a 7-point scale)."""
        return (self.points + 1) / 2


@dataclass(frozen=True)
class LikertItem:
    """One rating question: ``id`` names the column in the exported tables (``helpful``, ...)."""

    id: str
    prompt: str
    scale: Scale
    kind: ClassVar[str] = "likert"
    optional: ClassVar[bool] = False

    @property
    def anchors(self) -> tuple[str, ...]:
        return self.scale.anchors

    @property
    def points(self) -> int:
        return self.scale.points

    def anchor_text(self) -> str:
        """The two end anchors, and the middle one when the scale has an odd length."""
        k = self.points
        marks = [1, k] if k % 2 == 0 else [1, (k + 1) // 2, k]
        return " · ".join(f"{j} = {self.anchors[j - 1]}" for j in marks)

    def texts(self) -> tuple[str, ...]:
        """What the participant reads of this item besides its scale: the prompt."""
        return (self.prompt,)

    def check(self, value: object) -> int:
        """``value`` as an int in ``1..points``, else :class:`AnswerError` saying the range."""
        if isinstance(value, bool) or not isinstance(value, int | float) or value != int(value):
            raise AnswerError(
                f"item {self.id!r}: answer must be a whole number 1..{self.scale.points},"
                f" got {_kind_of(value)}"
            )
        answer = int(value)
        if not 1 <= answer <= self.scale.points:
            raise AnswerError(
                f"item {self.id!r}: answer {answer} is outside its {self.scale.points}-point"
                f" scale (1..{self.scale.points})"
            )
        return answer


@dataclass(frozen=True)
class ChoiceItem:
    """One of ``options``, answered with the option's text (stored as that text)."""

    id: str
    prompt: str
    options: tuple[str, ...]
    optional: bool = False
    kind: ClassVar[str] = "choice"

    def texts(self) -> tuple[str, ...]:
        return (self.prompt, *self.options)

    def check(self, value: object) -> str | None:
        """The chosen option, ``None`` for an optional item left empty; else AnswerError."""
        if _empty(value):
            return _left_empty(self)
        if isinstance(value, str) and value.strip() in self.options:
            return value.strip()
        raise AnswerError(
            f"item {self.id!r}: the answer must be one of its {len(self.options)} options"
            f" ({' | '.join(self.options)})"
        )

    def code(self, answer: str) -> int:
        """The 1-based position of ``answer`` among the options."""
        return self.options.index(answer) + 1


@dataclass(frozen=True)
class AttentionItem(ChoiceItem):
    """A choice with one ``correct`` option: an attention check ("please choose 'Often'")."""

    correct: str = ""
    kind: ClassVar[str] = "attention"

    def passed(self, answer: object) -> bool:
        return answer == self.correct


@dataclass(frozen=True)
class RetentionItem(ChoiceItem):
    """The end-of-study question whether the participant's data may be kept: the ``keep``
    option agrees; any other answer (or none) means their data are left out of export and
    analysis."""

    keep: str = ""
    kind: ClassVar[str] = "retention"

    def keeps(self, answer: object) -> bool:
        return answer == self.keep


@dataclass(frozen=True)
class NumberItem:
    """A number in ``minimum..maximum`` (whole if ``whole``); ``unit`` is shown beside it."""

    id: str
    prompt: str
    minimum: float
    maximum: float
    unit: str = ""
    whole: bool = True
    optional: bool = False
    kind: ClassVar[str] = "number"

    def texts(self) -> tuple[str, ...]:
        return (self.prompt, self.unit) if self.unit else (self.prompt,)

    def range_text(self) -> str:
        """``"a whole number from 18 to 99 (years)"``: what the field accepts."""
        what = "a whole number" if self.whole else "a number"
        unit = f" ({self.unit})" if self.unit else ""
        return f"{what} from {_num(self.minimum)} to {_num(self.maximum)}{unit}"

    def check(self, value: object) -> int | float | None:
        """The number (an int if ``whole``), ``None`` for an optional item left empty."""
        if _empty(value):
            return _left_empty(self)
        number = _parse_number(value)
        if (
            number is None
            or (self.whole and number != int(number))
            or not self.minimum <= number <= self.maximum
        ):
            raise AnswerError(f"item {self.id!r}: the answer must be {self.range_text()}")
        return int(number) if self.whole else number


@dataclass(frozen=True)
class TextItem:
    """Free text of at most ``max_length`` characters (after trimming spaces at both ends)."""

    id: str
    prompt: str
    max_length: int
    optional: bool = True
    kind: ClassVar[str] = "text"

    def texts(self) -> tuple[str, ...]:
        return (self.prompt,)

    def check(self, value: object) -> str | None:
        """The text, trimmed, line breaks as ``\\n``, control characters removed; ``None`` for
        an optional item left empty. Too long: AnswerError with the count, never the text."""
        if value is None:
            return _left_empty(self)
        if not isinstance(value, str):
            raise AnswerError(f"item {self.id!r}: the answer must be text, got {_kind_of(value)}")
        text = _CONTROL.sub("", value.replace("\r\n", "\n").replace("\r", "\n")).strip()
        if not text:
            return _left_empty(self)
        if len(text) > self.max_length:
            raise AnswerError(
                f"item {self.id!r}: the answer has {len(text)} characters; at most"
                f" {self.max_length} are kept, please shorten it"
            )
        return text


Item = LikertItem | ChoiceItem | NumberItem | TextItem
"""Any questionnaire item (attention and retention items are choice items)."""
Answer = int | float | str | None
"""A checked answer: Likert int, choice text, number, free text, or None (left empty)."""


@dataclass(frozen=True)
class Questionnaire:
    """All items of a protocol and the moments they are asked (module docstring).

    ``between_tasks`` pairs a task number k (1-based, in the participant's schedule order) with
    the items asked after that task's runs (and preference). ``points`` is the Likert scales'
    length."""

    points: int
    items: Mapping[str, Item]
    after_training: tuple[LikertItem, ...]
    after_run: tuple[LikertItem, ...]
    after_task: tuple[LikertItem, ...]
    before_training: tuple[Item, ...] = ()
    between_tasks: tuple[tuple[int, tuple[Item, ...]], ...] = ()
    closing: tuple[Item, ...] = ()

    def item(self, item_id: str) -> Item:
        try:
            return self.items[item_id]
        except KeyError:
            raise AnswerError(
                f"no questionnaire item {item_id!r}; items: {', '.join(self.items)}"
            ) from None

    def items_for(self, phase: str) -> tuple[Item, ...]:
        """The items asked at ``phase`` (one of :data:`PHASES`; ``between_tasks``: all of the
        pages after any task, in order)."""
        if phase not in PHASES:
            raise AnswerError(f"unknown questionnaire phase {phase!r}; one of {PHASES}")
        if phase == "between_tasks":
            return tuple(i for _, items in self.between_tasks for i in items)
        return tuple(getattr(self, phase))

    @property
    def once_items(self) -> tuple[Item, ...]:
        """Items asked once per participant (before training, between tasks, closing)."""
        return tuple(dict.fromkeys(i for p in ONCE_PHASES for i in self.items_for(p)))

    @property
    def attention_checks(self) -> tuple[AttentionItem, ...]:
        """The attention checks asked (an item defined but asked nowhere is not one)."""
        return tuple(i for i in self.once_items if isinstance(i, AttentionItem))

    @property
    def retention(self) -> RetentionItem | None:
        """The data-retention question, if the protocol asks one (at the end, ``closing``)."""
        found = [i for i in self.closing if isinstance(i, RetentionItem)]
        return found[0] if found else None

    def check_answer(self, item_id: str, value: object) -> Answer:
        """Validate one answer against its item; returns it normalised."""
        return self.item(item_id).check(value)

    def check_answers(self, phase: str, answers: Mapping[str, object]) -> dict[str, Answer]:
        """Validate a whole page of answers: exactly the items of ``phase``, each checked."""
        expected = [i.id for i in self.items_for(phase)]
        missing = [i for i in expected if i not in answers]
        extra = [k for k in answers if k not in expected]
        if missing or extra:
            raise AnswerError(
                f"{phase}: expected answers to {expected}; missing {missing}, unexpected {extra}"
            )
        return {i: self.check_answer(i, answers[i]) for i in expected}


def _empty(value: object) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


def _left_empty(item: ChoiceItem | NumberItem | TextItem) -> None:
    if not item.optional:
        raise AnswerError(f"item {item.id!r} needs an answer")
    return None


def _kind_of(value: object) -> str:
    """A short description of a refused value that never quotes a participant's text."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return repr(value)
    return f"a {type(value).__name__}"


def _parse_number(value: object) -> float | None:
    """A finite number from an int, float or short numeric text (``"2.5"``, ``"2,5"``)."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        number = float(value)
    elif isinstance(value, str) and len(value) <= MAX_NUMBER_CHARS:
        text = value.strip().replace(" ", "")
        if text.count(",") == 1 and "." not in text:
            text = text.replace(",", ".")
        if not re.fullmatch(r"[+-]?(\d+(\.\d*)?|\.\d+)", text):
            return None
        number = float(text)
    else:
        return None
    return number if math.isfinite(number) else None


def _num(x: float) -> str:
    return f"{x:g}"

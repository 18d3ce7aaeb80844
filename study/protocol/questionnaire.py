"""Likert items, their scales, and when they are asked.

A :class:`Scale` is an ordered tuple of anchors, one per point (``anchors[0]`` labels the answer
1). A :class:`LikertItem` is a prompt on a scale. The :class:`Questionnaire` says which items are
asked after the training runs (ratings of the unassisted robot, the baseline covariate), after
each assisted run (one rating per condition) and after both runs of a task (the preference
between its two runs: 1 = strongly preferred the first run, ``points`` = the second).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from study.protocol.errors import AnswerError

PHASES = ("after_training", "after_run", "after_task")


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
    """One question: ``id`` names the column in the exported tables (``helpful``, ...)."""

    id: str
    prompt: str
    scale: Scale

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

    def check(self, value: object) -> int:
        """``value`` as an int in ``1..points``, else :class:`AnswerError` saying the range."""
        if isinstance(value, bool) or not isinstance(value, int | float) or value != int(value):
            raise AnswerError(
                f"item {self.id!r}: answer must be a whole number 1..{self.scale.points},"
                f" got {value!r}"
            )
        answer = int(value)
        if not 1 <= answer <= self.scale.points:
            raise AnswerError(
                f"item {self.id!r}: answer {answer} is outside its {self.scale.points}-point"
                f" scale (1..{self.scale.points})"
            )
        return answer


@dataclass(frozen=True)
class Questionnaire:
    """All items of a protocol and the three moments they are asked."""

    points: int
    items: Mapping[str, LikertItem]
    after_training: tuple[LikertItem, ...]
    after_run: tuple[LikertItem, ...]
    after_task: tuple[LikertItem, ...]

    def item(self, item_id: str) -> LikertItem:
        try:
            return self.items[item_id]
        except KeyError:
            raise AnswerError(
                f"no questionnaire item {item_id!r}; items: {', '.join(self.items)}"
            ) from None

    def items_for(self, phase: str) -> tuple[LikertItem, ...]:
        """The items asked at ``phase`` (one of :data:`PHASES`)."""
        if phase not in PHASES:
            raise AnswerError(f"unknown questionnaire phase {phase!r}; one of {PHASES}")
        return tuple(getattr(self, phase))

    def check_answer(self, item_id: str, value: object) -> int:
        """Validate one answer against its item's scale; returns it as an int."""
        return self.item(item_id).check(value)

    def check_answers(self, phase: str, answers: Mapping[str, object]) -> dict[str, int]:
        """Validate a whole page of answers: exactly the items of ``phase``, each on its scale."""
        expected = [i.id for i in self.items_for(phase)]
        missing = [i for i in expected if i not in answers]
        extra = [k for k in answers if k not in expected]
        if missing or extra:
            raise AnswerError(
                f"{phase}: expected answers to {expected}; missing {missing}, unexpected {extra}"
            )
        return {i: self.check_answer(i, answers[i]) for i in expected}

"""Scripted answers for headless sessions: a fixed, seeded rule from what the participant lived.

The rule sees only what a participant sees - the screen and how their own runs went (time and
whether they picked the object up) - never the condition:

- ratings (after a run, and after training): ``1 + 6 (1 - T / T_limit)`` for a success, 2 for
  a failure, plus uniform noise in ``[-noise, noise]``, clipped to the scale;
- preference (after both runs of a task): ``4 + 3 (c1 - c2) / max(c1, c2)`` with ``c`` the run's
  time (1.5 ``T_limit`` for a failure), so a faster second run pulls towards "second run";
- the other kinds (:func:`profile_answer`, shared with the simulated participants): a choice
  drawn uniformly, an attention check answered correctly but for a lapse with probability
  ``lapse``, the data-retention question answered "keep", a number drawn towards the low end
  of its range, an optional free text left empty (a required one: "No comment.").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from study.protocol import (
    Answer,
    AttentionItem,
    ChoiceItem,
    Item,
    LikertItem,
    NumberItem,
    RetentionItem,
    TextItem,
)
from study.session.screen import Screen
from study.session.trial_run import TrialSummary


@dataclass(frozen=True)
class ScriptedRun:
    """One run as the participant lived it."""

    success: bool
    duration_s: float
    time_limit_s: float

    @property
    def cost(self) -> float:
        return self.duration_s if self.success else 1.5 * self.time_limit_s


class ScriptedAnswers:
    """The rule of the module docstring, seeded."""

    def __init__(self, *, seed: int = 0, noise: int = 1) -> None:
        self.rng = np.random.default_rng(seed)
        self.noise = noise
        self.runs: list[ScriptedRun] = []

    def observe(self, summary: TrialSummary | None, *, time_limit_s: float) -> None:
        """Remember a finished run (``None``: aborted, not experienced to the end)."""
        if summary is not None:
            self.runs.append(ScriptedRun(summary.success, summary.duration_s, time_limit_s))

    def answer(self, screen: Screen) -> dict[str, Answer]:
        """Answers to every item on ``screen``."""
        if screen.questionnaire == "after_task":
            base = self._preference()
        else:
            base = self._rating()
        out: dict[str, Answer] = {}
        for item in screen.items:
            if not isinstance(item, LikertItem):
                out[item.id] = profile_answer(item, self.rng)
                continue
            jitter = int(self.rng.integers(-self.noise, self.noise + 1)) if self.noise else 0
            out[item.id] = int(np.clip(round(base) + jitter, 1, item.points))
        return out

    def _rating(self) -> float:
        if not self.runs:
            return 4.0
        run = self.runs[-1]
        if not run.success:
            return 2.0
        return 1.0 + 6.0 * max(0.0, 1.0 - run.duration_s / run.time_limit_s)

    def _preference(self) -> float:
        if len(self.runs) < 2:
            return 4.0
        first, second = self.runs[-2].cost, self.runs[-1].cost
        return 4.0 + 3.0 * (first - second) / max(first, second, 1e-9)


def profile_answer(item: Item, rng: np.random.Generator, *, lapse: float = 0.0) -> Answer:
    """A seeded answer to a non-Likert item (module docstring)."""
    if isinstance(item, RetentionItem):
        return item.keep
    if isinstance(item, AttentionItem):
        wrong = [o for o in item.options if o != item.correct]
        if wrong and rng.random() < lapse:
            return wrong[int(rng.integers(len(wrong)))]
        return item.correct
    if isinstance(item, ChoiceItem):
        return item.options[int(rng.integers(len(item.options)))]
    if isinstance(item, NumberItem):
        value = item.minimum + (item.maximum - item.minimum) * float(rng.beta(1.3, 4.0))
        return round(value) if item.whole else round(value, 2)
    if isinstance(item, TextItem):
        return None if item.optional else "No comment."
    sample = getattr(item, "sample", None)  # a registered kind's own (study.protocol.item_kinds)
    if sample is not None:
        answer: Answer = sample(rng)
        return answer
    raise TypeError(f"no scripted answer for a {type(item).__name__}: give it sample(rng)")

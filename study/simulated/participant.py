"""``SimulatedParticipant``: one simulated person across a whole session.

It plays both parts the headless session loop (``study.session.headless.run_headless``) asks of a
participant: the input factory (a fresh :class:`~study.simulated.interface.InterfaceUser` --
the page's gizmo or keys, as the population draws -- for every trial attempt, seeded by the
participant and the attempt's seed) and the answerer
(``observe`` each finished run, ``answer`` each questionnaire screen). It sees what a
participant sees - the screen (which set of items is asked, their scales) and its own runs
(duration, outcome, the motion it saw) - never the task, mode or correctness of a step.

Runs finished before the ``after_training`` questionnaire are the practice runs: they set the
participant's references (``QuestionnaireModel.observe_training``) and are what the baseline
items rate. ``after_run`` items rate the last run; ``after_task`` asks the preference between the
last two runs (1 = the first run). Items asked once (demographics, attention checks, a comment,
the data-retention question) get ``study.session.answers.profile_answer``'s seeded answers from
a stream of their own, so adding them to a protocol leaves every rating as it was; a Likert item
among them rates every run so far.

This is the default simulated-user model, ``interface`` (:data:`INTERFACE_MODEL`, registered in
:mod:`study.simulated.models`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from study.protocol import Answer, LikertItem
from study.protocol.questionnaire import ONCE_PHASES
from study.session.answers import profile_answer
from study.simulated.errors import SimulationRunError
from study.simulated.experience import RunExperience
from study.simulated.interface import InterfaceUser
from study.simulated.models import UserModel, register
from study.simulated.population import INTERFACE_SECTIONS, ParticipantParams, participant_rng
from study.simulated.questionnaire import QuestionnaireModel
from study.simulated.trust import Trust

if TYPE_CHECKING:
    from app.trial import TrialConfig
    from study.session.screen import Screen
    from study.session.trial_run import TrialSummary


ATTENTION_LAPSE = 0.05
"""Chance that a simulated participant fails an attention check (answers another option)."""


class SimulatedParticipant:
    """Input factory + answerer for ``run_headless`` (see module docstring)."""

    def __init__(self, params: ParticipantParams) -> None:
        self.params = params
        self.questionnaire = QuestionnaireModel(
            params.questionnaire, rng=participant_rng(params.index, seed=params.seed, stream=1)
        )
        self.profile_rng = participant_rng(params.index, seed=params.seed, stream=3)
        self.trust = Trust(params.trust)
        """Trust in the robot, carried from run to run (:mod:`study.simulated.trust`)."""
        self.runs: list[RunExperience] = []
        self.training_runs: list[RunExperience] = []
        self._trained = False
        self._user: InterfaceUser | None = None

    # ---- input factory ----------------------------------------------------------------------
    def __call__(self, config: TrialConfig, seed: int) -> InterfaceUser:
        """A fresh user for one trial attempt, with this participant's trust in the robot as
        their earlier runs left it. Of ``config`` only the page's input mapping is read (the
        interface, which the participant uses); it carries the condition too, which a
        participant does not know."""
        rng = np.random.default_rng([self.params.seed, self.params.index, 2, int(seed)])
        self.trust.new_run()
        mapping = str(config.extra.get("input_mapping", "absolute"))
        self._user = InterfaceUser(self.params, rng=rng, trust=self.trust, mapping=mapping)
        return self._user

    # ---- answerer ---------------------------------------------------------------------------
    def observe(self, summary: TrialSummary | None, *, time_limit_s: float) -> None:
        """Remember how the run just finished went (``None``: aborted, not lived to the end)."""
        del time_limit_s
        user, self._user = self._user, None
        if summary is None or user is None:
            return
        self.runs.append(user.experience(duration_s=summary.duration_s, success=summary.success))

    def answer(self, screen: Screen) -> dict[str, Answer]:
        """Answers to every item on a questionnaire screen."""
        if not screen.items:
            raise SimulationRunError(f"answer: screen {screen.title!r} asks no items")
        if screen.questionnaire in ONCE_PHASES:
            return self._answer_once(screen)
        if screen.questionnaire == "after_training":
            self._finish_training(keep_last=0)
            return self._rate(screen, self.training_runs or self.runs[-1:])
        self._finish_training(keep_last=1)
        if not self.runs:
            raise SimulationRunError(
                f"answer: {screen.questionnaire} items asked before any run was observed"
            )
        if screen.questionnaire == "after_task":
            if len(self.runs) < 2:
                raise SimulationRunError("answer: a preference needs two runs; observed one")
            first, second = self.runs[-2], self.runs[-1]
            return {
                item.id: self.questionnaire.prefer(first, second, points=item.points)
                for item in screen.items
            }
        return self._rate(screen, self.runs[-1])

    def _rate(self, screen: Screen, runs: RunExperience | list[RunExperience]) -> dict[str, Answer]:
        out: dict[str, Answer] = {}
        for item in screen.items:
            if isinstance(item, LikertItem):
                out.update(self.questionnaire.rate([item.id], runs, points=item.points))
        return out

    def _answer_once(self, screen: Screen) -> dict[str, Answer]:
        out: dict[str, Answer] = {}
        for item in screen.items:
            if not isinstance(item, LikertItem):
                out[item.id] = profile_answer(item, self.profile_rng, lapse=ATTENTION_LAPSE)
            elif self.runs:
                out.update(self.questionnaire.rate([item.id], self.runs, points=item.points))
            else:  # nothing lived yet to rate: the neutral answer
                out[item.id] = round(item.scale.midpoint)
        return out

    def _finish_training(self, *, keep_last: int) -> None:
        """The runs so far (but the last ``keep_last``) were practice: they become the
        questionnaire's references. Happens once."""
        if self._trained:
            return
        self._trained = True
        self.training_runs = self.runs[: len(self.runs) - keep_last]
        self.questionnaire.observe_training(self.training_runs)


INTERFACE_MODEL = register(
    UserModel(
        name="interface",
        doc="a person on the page's gizmo or keys: goal-directed minimum-jerk movement, reaction"
        " delay, surprise, trust, questionnaire answers from the runs' experience",
        sections=INTERFACE_SECTIONS,
        params=ParticipantParams,
        participant=SimulatedParticipant,
    )
)
"""The default simulated-user model."""

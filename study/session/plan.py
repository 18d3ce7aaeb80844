"""The session plan: the flat list of steps one participant goes through.

    consent -> before-training items (e.g. demographics)
            -> training run 1..R -> after-training items (baseline)
            -> for each task k in schedule order:
                   run (first mode) -> after-run items -> run (second mode) -> after-run items
                   -> after-task item (preference: first run vs second run)
                   -> the between-tasks page after task k, if the protocol has one
            -> closing items (comment, data retention) -> debrief

A session's ``cursor`` is the index of its current step (``len(steps)`` = finished), so the
store can say exactly where an interrupted session resumes. Built from the protocol and the
participant's stored assignment rows (``study.schedule`` decides them at enrolment).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

from study.protocol import TRAINING_MODE, Item, Protocol
from study.store import AssignmentRecord

StepKind = Literal["consent", "trial", "questions", "debrief"]
RUN_LABELS = ("first", "second", "third", "fourth", "fifth", "sixth")


def run_label(run: int) -> str:
    """``1 -> "first"``, ``2 -> "second"`` ... (the ``run`` column of trials and ratings)."""
    return RUN_LABELS[run - 1] if 1 <= run <= len(RUN_LABELS) else f"run{run}"


@dataclass(frozen=True)
class Step:
    """One step of the plan.

    ``phase`` is ``"training"`` or ``"task"`` (consent, debrief and the questions asked once
    per participant use ``"session"``);
    ``trial_number`` counts trial steps 1..n (progress "trial 3 of 11"); ``position`` counts task
    trials 1..8; ``questionnaire`` is the protocol's questionnaire phase for question steps;
    ``rates_step`` is the trial step an after-run question step is about; ``task_steps`` the trial
    steps an after-task (preference) step compares, or the practice runs an after-training step
    asks about.
    """

    index: int
    kind: StepKind
    phase: str
    task: str | None = None
    mode: str | None = None
    run: str | None = None
    position: int | None = None
    trial_number: int | None = None
    task_number: int | None = None
    questionnaire: str | None = None
    items: tuple[Item, ...] = ()
    rates_step: int | None = None
    task_steps: tuple[int, ...] = ()


@dataclass(frozen=True)
class Plan:
    steps: tuple[Step, ...]
    n_trials: int
    n_tasks: int

    def __len__(self) -> int:
        return len(self.steps)

    def __getitem__(self, index: int) -> Step:
        return self.steps[index]

    def dependents(self, trial_step: int, *, skipped: Iterable[int] = ()) -> tuple[int, ...]:
        """Question steps that lose their subject if ``trial_step`` is skipped (``skipped``:
        the steps skipped before): its after-run items, its task's preference, and the
        after-training items once every practice run is skipped."""
        gone = {trial_step, *skipped}

        def loses(s: Step) -> bool:
            if s.rates_step == trial_step:
                return True
            if trial_step not in s.task_steps:
                return False
            return s.questionnaire != "after_training" or gone.issuperset(s.task_steps)

        return tuple(s.index for s in self.steps if loses(s))


def build_plan(protocol: Protocol, assignments: Sequence[AssignmentRecord]) -> Plan:
    """The plan for a participant whose task runs are ``assignments`` (ordered by position)."""
    q = protocol.questionnaire
    steps: list[Step] = []

    def add(kind: StepKind, phase: str, **kw: object) -> Step:
        step = Step(len(steps), kind, phase, **kw)  # type: ignore[arg-type]
        steps.append(step)
        return step

    add("consent", "session")
    if q.before_training:
        add("questions", "session", questionnaire="before_training", items=q.before_training)
    between = dict(q.between_tasks)
    trial_number = 0
    training = protocol.training.runs
    practice = []
    for _ in range(training):
        trial_number += 1
        step = add("trial", "training", task=None, mode=TRAINING_MODE, trial_number=trial_number)
        practice.append(step.index)
    if training and q.after_training:
        add(
            "questions",
            "training",
            mode=TRAINING_MODE,
            questionnaire="after_training",
            items=tuple(q.after_training),
            task_steps=tuple(practice),
        )
    rows = sorted(assignments, key=lambda a: a.position)
    task_number = 0
    i = 0
    while i < len(rows):
        task = rows[i].task
        task_number += 1
        runs = []
        while i < len(rows) and rows[i].task == task:
            a = rows[i]
            trial_number += 1
            trial = add(
                "trial",
                "task",
                task=task,
                mode=a.mode,
                run=a.run,
                position=a.position,
                trial_number=trial_number,
                task_number=task_number,
            )
            runs.append(trial.index)
            if q.after_run:
                add(
                    "questions",
                    "task",
                    task=task,
                    mode=a.mode,
                    run=a.run,
                    position=a.position,
                    task_number=task_number,
                    questionnaire="after_run",
                    items=tuple(q.after_run),
                    rates_step=trial.index,
                )
            i += 1
        if q.after_task:
            add(
                "questions",
                "task",
                task=task,
                task_number=task_number,
                questionnaire="after_task",
                items=tuple(q.after_task),
                task_steps=tuple(runs),
            )
        if task_number in between:
            add("questions", "session", questionnaire="between_tasks", items=between[task_number])
    if q.closing:
        add("questions", "session", questionnaire="closing", items=q.closing)
    add("debrief", "session")
    return Plan(steps=tuple(steps), n_trials=trial_number, n_tasks=task_number)

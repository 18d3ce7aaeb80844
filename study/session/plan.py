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
from itertools import groupby
from typing import Literal

from study.protocol import TRAINING_MODE, Item, Protocol, Questionnaire
from study.session.screen import Progress
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
    ``trial_number`` counts trial steps 1..n (the store's numbering, practice runs included);
    ``run_number`` is a trial's number as the participant counts it, within its phase ("Practice
    run 2 of 3", "Run 5 of 8"); ``position`` counts task trials 1..8; ``questionnaire`` is the protocol's questionnaire phase for question steps;
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
    run_number: int | None = None
    task_number: int | None = None
    questionnaire: str | None = None
    items: tuple[Item, ...] = ()
    rates_step: int | None = None
    task_steps: tuple[int, ...] = ()


@dataclass(frozen=True)
class Plan:
    """The steps, with how many trials (``n_trials``), tasks, practice runs and task runs
    (``n_runs``: the main part's runs, as the consent counts them) they hold."""

    steps: tuple[Step, ...]
    n_trials: int
    n_tasks: int
    n_practice: int = 0
    n_runs: int = 0

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


def run_progress(plan: Plan, step: Step) -> Progress:
    """Trial step ``step`` as the participant's page counts it: "Practice run 2 of 3" among
    the practice runs, "Run 5 of 8" among the main part's (``run`` 0 for any other step)."""
    if step.run_number is None:
        return Progress(0, plan.n_runs)
    if step.phase == "training":
        return Progress(step.run_number, plan.n_practice, practice=True)
    return Progress(step.run_number, plan.n_runs)


def build_plan(protocol: Protocol, assignments: Sequence[AssignmentRecord]) -> Plan:
    """The plan for a participant whose task runs are ``assignments`` (ordered by position):
    consent, questions before training, the practice runs and their questions, each task's
    runs (each run followed by its questions, the task by its own), questions between tasks,
    closing questions, debrief."""
    q = protocol.questionnaire
    steps = _Steps()
    steps.add("consent", "session")
    if q.before_training:
        steps.add("questions", "session", questionnaire="before_training", items=q.before_training)
    _training(steps, protocol)
    between = dict(q.between_tasks)
    rows = sorted(assignments, key=lambda a: a.position)
    # nested: a task's runs are one block; williams: every run is its own block
    block = (lambda a: a.task) if protocol.scheme == "nested" else (lambda a: a.position)
    for task_number, (_, runs) in enumerate(groupby(rows, key=block), start=1):
        block_runs = list(runs)
        _task(steps, q, block_runs[0].task, block_runs, task_number=task_number)
        if task_number in between:
            steps.add(
                "questions", "session", questionnaire="between_tasks", items=between[task_number]
            )
    if q.closing:
        steps.add("questions", "session", questionnaire="closing", items=q.closing)
    steps.add("debrief", "session")
    return Plan(
        steps=tuple(steps.steps),
        n_trials=steps.trials,
        n_tasks=steps.tasks,
        n_practice=steps.runs["training"],
        n_runs=steps.runs["task"],
    )


class _Steps:
    """The plan's steps as they are added, numbered in order; counts trials (all, and per
    phase: the participant's run numbers) and tasks."""

    def __init__(self) -> None:
        self.steps: list[Step] = []
        self.trials = 0
        self.tasks = 0
        self.runs = {"training": 0, "task": 0}

    def add(self, kind: StepKind, phase: str, **kw: object) -> Step:
        if kind == "trial":
            self.trials += 1
            self.runs[phase] += 1
            kw["trial_number"] = self.trials
            kw["run_number"] = self.runs[phase]
        step = Step(len(self.steps), kind, phase, **kw)  # type: ignore[arg-type]
        self.steps.append(step)
        return step


def _training(steps: _Steps, protocol: Protocol) -> None:
    """The practice runs and, after them, the after-training questions about them."""
    q = protocol.questionnaire
    practice = [
        steps.add("trial", "training", task=None, mode=TRAINING_MODE).index
        for _ in range(protocol.training.runs)
    ]
    if practice and q.after_training:
        steps.add(
            "questions",
            "training",
            mode=TRAINING_MODE,
            questionnaire="after_training",
            items=tuple(q.after_training),
            task_steps=tuple(practice),
        )


def _task(
    steps: _Steps, q: Questionnaire, task: str, runs: list[AssignmentRecord], *, task_number: int
) -> None:
    """One task's consecutive runs, each followed by the after-run questions, then the
    after-task questions about all of them."""
    steps.tasks = task_number
    trial_steps = []
    for a in runs:
        where = {"task": task, "mode": a.mode, "run": a.run, "position": a.position}
        trial = steps.add("trial", "task", **where, task_number=task_number)
        trial_steps.append(trial.index)
        if q.after_run:
            steps.add(
                "questions",
                "task",
                **where,
                task_number=task_number,
                questionnaire="after_run",
                items=tuple(q.after_run),
                rates_step=trial.index,
            )
    if q.after_task:
        steps.add(
            "questions",
            "task",
            task=task,
            task_number=task_number,
            questionnaire="after_task",
            items=tuple(q.after_task),
            task_steps=tuple(trial_steps),
        )

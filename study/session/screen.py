"""What the participant should see now (``Screen``) and what the experimenter sees (``Overview``).

``Screen`` is small, typed and blind: its text comes from the protocol's participant-facing
texts (checked on load never to name a condition) and its fields carry no task, mode or
correctness name, so a UI can send it to the participant's browser as is. Its items are the
protocol's own items (``study.protocol.questionnaire``: an id, a prompt, a scale or options):
none of them names a condition either. ``Overview`` is for the experimenter only (127.0.0.1)
and carries the full condition.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from study.protocol import Item

Phase = Literal["waiting", "consent", "ready", "running", "questions", "debrief", "done"]
"""``waiting``: before the experimenter starts (or continues) the session in this process;
``ready``: a trial is next and waits for Start; ``running``: a trial runs; ``questions``: items
to answer; ``done``: completed, withdrawn or ended (see ``Overview.status``)."""


@dataclass(frozen=True)
class Progress:
    """Run ``run`` of ``of`` as the participant counts them, as the consent does: the practice
    runs ("Practice run 2 of 3", ``practice``) apart from the main part's runs ("Run 5 of 8").
    ``run`` 0: before the first run (no text)."""

    run: int
    of: int
    practice: bool = False

    @property
    def text(self) -> str:
        if not self.run:
            return ""
        return f"{'Practice run' if self.practice else 'Run'} {self.run} of {self.of}"


@dataclass(frozen=True)
class Screen:
    """The participant's current screen.

    ``revision`` grows with every change of the session (a UI may re-render when it changes);
    ``actions`` are the participant actions valid now (``agree``, ``start_trial``, ``answer``,
    ``finish``); ``paused`` overlays any phase; ``questionnaire`` says which set of items is
    shown (``before_training``, ``after_training``, ``after_run``, ``after_task`` -- the
    preference between the two runs just done --, ``between_tasks`` or ``closing``).
    """

    phase: Phase
    title: str
    text: str
    progress: Progress
    items: tuple[Item, ...] = ()
    actions: tuple[str, ...] = ()
    paused: bool = False
    questionnaire: str | None = None
    revision: int = 0


@dataclass(frozen=True)
class Overview:
    """The experimenter's view of a session: the full condition of the current step."""

    participant: str
    session_id: int
    status: str
    phase: Phase
    paused: bool
    step: int
    steps: int
    step_kind: str | None
    training_or_task: str | None
    task: str | None
    difficulty: str | None
    correctness: str | None
    mode: str | None
    run: str | None
    attempt: int | None
    trial_id: int | None
    trials_completed: int
    ratings: int
    schedule_row: int
    schedule: tuple[tuple[int, str, str, str], ...]
    """``(position, task, run, mode)`` of every task trial."""
    skipped_steps: tuple[int, ...]
    experimenter_actions: tuple[str, ...]
    group: str = ""
    """The participant's between-subjects levels, ``mapping=relative`` ("" without any)."""

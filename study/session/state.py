"""``RunState``: the one owner of a session's run state in this process.

Where the participant is (``cursor`` into the plan, the ``skipped`` steps), the session's
``status``, whether it was ``started`` in this process, whether it is ``paused`` (and by what),
the ``active`` trial run and the ``revision`` a UI re-renders on. Every other part asks it:
``TrialRun.paused`` reads ``paused`` here, the views compute the phase from it, the live server
asks the session. Nothing else keeps a copy of "paused" or "running".

The app-level ``app.trial.Trial`` keeps its own pause flag (it runs without a session too, and
marks its samples "paused"/"resumed"); the state pushes every change down to it through the
active run (``TrialRun.follow_pause``), so it always mirrors this one.

Not thread-safe by itself: the session's lock guards every write. The control thread reads
``paused`` and ``active`` without it (single attribute reads).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from study.session.plan import Plan, Step
from study.session.screen import Phase
from study.session.trial_run import TrialRun

FINAL_STATUSES = ("completed", "withdrawn", "ended")

PauseCause = Literal["experimenter", "tab_lost"]
"""Who paused: the experimenter's action (or a control fault), or the participant's tab going
away (the participant may then resume it themselves from their next tab)."""


@dataclass
class RunState:
    """The run state of one session (see module docstring)."""

    status: str
    cursor: int
    skipped: set[int] = field(default_factory=set)
    started: bool = False
    paused_by: PauseCause | None = None
    closed: bool = False
    active: TrialRun | None = None
    revision: int = 0

    @property
    def paused(self) -> bool:
        return self.paused_by is not None

    @property
    def finished(self) -> bool:
        return self.status in FINAL_STATUSES

    def set_paused(self, cause: PauseCause | None) -> None:
        """Pause (``cause`` given) or resume (``None``), the active run's trial with it."""
        self.paused_by = cause
        if self.active is not None:
            self.active.follow_pause()

    def step(self, plan: Plan) -> Step | None:
        """The current step, ``None`` past the end."""
        return plan[self.cursor] if self.cursor < len(plan) else None

    def phase(self, plan: Plan) -> Phase:
        if self.finished:
            return "done"
        if not self.started:
            return "waiting"
        step = self.step(plan)
        if step is None:
            return "done"
        if step.kind == "trial":
            return "running" if self.active is not None else "ready"
        return step.kind  # consent, questions, debrief

    def saved(self) -> tuple[int, set[int]]:
        """What a failed transaction must put back (see ``restore``)."""
        return self.cursor, set(self.skipped)

    def restore(self, saved: tuple[int, set[int]]) -> None:
        self.cursor, self.skipped = saved[0], saved[1]


__all__ = ["FINAL_STATUSES", "PauseCause", "RunState"]

"""``Steps``: what the plan, the run state and the store say about the session's steps, and the
guards every action checks first (is it open, is it live, is this the right screen).

Read-only: it never writes (``Ledger`` does). Called with the session lock held.
"""

from __future__ import annotations

from app.trial import TrialConfig
from study.protocol import Item, Protocol
from study.session.errors import SessionStateError
from study.session.ledger import Ledger
from study.session.plan import Plan, Step, run_progress
from study.session.screen import Phase, Progress
from study.session.state import RunState
from study.store import Store

PARTICIPANT_ACTIONS: dict[Phase, tuple[str, ...]] = {
    "consent": ("agree",),
    "ready": ("start_trial",),
    "questions": ("answer",),
    "debrief": ("finish",),
}
"""The participant actions valid on each screen (the only place they are listed)."""


class Steps:
    """Queries over one session's plan, state and stored rows (see module docstring)."""

    def __init__(
        self, *, plan: Plan, state: RunState, protocol: Protocol, store: Store, ledger: Ledger
    ) -> None:
        self.plan = plan
        self.state = state
        self.protocol = protocol
        self.store = store
        self.ledger = ledger
        self.session_id = ledger.info.session_id
        self.schedule_row = ledger.info.schedule_row
        self.texts = protocol.texts.for_link() if ledger.info.by_link else protocol.texts
        """The participant's texts (``Texts.for_link`` for one who came by the open link)."""

    # ---- where we are ---------------------------------------------------------------------------
    def current(self) -> Step | None:
        return self.state.step(self.plan)

    def phase(self) -> Phase:
        return self.state.phase(self.plan)

    def next_step(self, index: int) -> int:
        """The step after ``index``, passing skipped ones (the debrief is never skipped)."""
        nxt = index + 1
        while nxt < len(self.plan) - 1 and nxt in self.state.skipped:
            nxt += 1
        return nxt

    def progress(self) -> Progress:
        """The run shown: the current trial step's, else the last one passed (practice runs
        and the main part's runs counted apart, as the consent counts them)."""
        steps = self.plan.steps[: self.state.cursor + 1]
        last = next((s for s in reversed(steps) if s.run_number), None)
        return Progress(0, self.plan.n_runs) if last is None else run_progress(self.plan, last)

    def next_attempt(self, step: int) -> int:
        trials = self.store.trials(session_id=self.session_id)
        return max((t.attempt for t in trials if t.step == step), default=0) + 1

    def config(self, step: Step) -> TrialConfig:
        if step.phase == "training":
            return self.protocol.training_config(row=self.schedule_row)
        return self.protocol.trial_config(step.task or "", step.mode or "", row=self.schedule_row)

    def pending_items(self, step: Step) -> list[Item]:
        """The step's items not yet answered (ratings and other answers alike)."""
        ratings = self.store.ratings(session_id=self.session_id)
        answers = self.store.answers(session_id=self.session_id)
        answered = {r.item for r in [*ratings, *answers] if r.step == step.index}
        return [i for i in step.items if i.id not in answered]

    def rated_trial(self, step: Step) -> int | None:
        """The completed trial attempt an after-run item is about (``None`` for other items)."""
        if step.rates_step is None:
            return None
        completed = [
            t.trial_id
            for t in self.store.trials(session_id=self.session_id)
            if t.step == step.rates_step and t.status == "completed"
        ]
        return completed[-1] if completed else None

    def redo_target(self) -> tuple[int, int]:
        """The completed trial just before the cursor that ``redo`` may run again."""
        cursor, step = self.state.cursor, self.current()
        prev = cursor - 1
        if prev < 0 or self.plan[prev].kind != "trial" or prev in self.state.skipped:
            raise SessionStateError(
                "nothing to redo: no trial is running and the previous step is not a completed "
                "trial"
            )
        trials = self.store.trials(session_id=self.session_id)
        if any(t.step == cursor for t in trials) or (
            step is not None
            and step.kind == "questions"
            and self.pending_items(step) != list(step.items)
        ):
            raise SessionStateError(
                "cannot redo the previous trial: the step after it has already started or been "
                "answered"
            )
        done = [t.trial_id for t in trials if t.step == prev and t.status == "completed"]
        if not done:
            raise SessionStateError("nothing to redo: the previous trial has no completed attempt")
        return prev, done[-1]

    # ---- guards ---------------------------------------------------------------------------------
    def require_live(self, action: str) -> None:
        """The session is open and started, not finished."""
        self.ledger.require_open()
        phase = self.phase()
        if phase in ("waiting", "done"):
            raise SessionStateError(
                f"cannot {action}: the session is {self.state.status if phase == 'done' else phase}"
                f"{'' if phase == 'done' else ' (call start() first)'}"
            )

    def require_phase(self, *phases: Phase, action: str) -> Step:
        """The current step, if the screen is one of ``phases`` and the session not paused."""
        self.ledger.require_open()
        phase = self.phase()
        if phase not in phases:
            valid = ", ".join(PARTICIPANT_ACTIONS.get(phase, ())) or "none"
            raise SessionStateError(
                f"cannot {action} on the {phase} screen (status {self.state.status}); "
                f"participant actions valid now: {valid}"
            )
        if self.state.paused and action != "trial_config":
            raise SessionStateError(f"cannot {action}: the session is paused (resume() first)")
        step = self.current()
        assert step is not None or phase == "waiting"
        return step  # type: ignore[return-value]


__all__ = ["PARTICIPANT_ACTIONS", "Steps"]

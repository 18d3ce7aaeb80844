"""What a session shows, as functions of its state: the participant's blind ``Screen``, the
experimenter's ``Overview`` and the experimenter actions valid now.

Called with the session lock held; they read (``Steps``, the store), never write.
"""

from __future__ import annotations

from collections.abc import Mapping

from study.protocol import Item
from study.session.errors import SessionStateError
from study.session.ledger import SessionInfo
from study.session.plan import Plan, Step
from study.session.screen import Overview, Progress, Screen
from study.session.steps import PARTICIPANT_ACTIONS, Steps

EXPERIMENTER_ACTIONS: tuple[str, ...] = (
    "start",
    "pause",
    "resume",
    "redo",
    "skip",
    "withdraw",
    "end",
)
"""Every experimenter action, in the console's button order (the only place they are listed)."""

NEEDS_REASON: frozenset[str] = frozenset({"redo", "skip", "withdraw", "end"})
"""The experimenter actions that take a ``reason`` for the record."""


INTRODUCTIONS = {
    "after_task": "preference",
    "before_training": "before_training",
    "between_tasks": "between_tasks",
    "closing": "closing",
}
"""The instructions text introducing each questionnaire moment (``rating`` for the others)."""


RUN_QUESTIONNAIRES = ("after_run", "after_task")
"""The questions about the run (or the task's two runs) just done: the page shows that run's
number above them; above any other questions (the practice's, a break's, the closing ones) a
run number would say where the participant is not."""


def screen(steps: Steps, *, revision: int) -> Screen:
    """What the participant should see now (no condition names anywhere)."""
    state, protocol = steps.state, steps.protocol
    phase = steps.phase()
    texts = steps.texts
    step = steps.current()
    progress = steps.progress()
    items: tuple[Item, ...] = ()
    actions = PARTICIPANT_ACTIONS.get(phase, ())
    if phase == "waiting":
        title, text = "Before you start", texts.instructions["welcome"]  # its text greets
    elif phase == "consent":
        title, text = "Consent", texts.consent
    elif phase in ("ready", "running") and step is not None:
        title = progress.text  # "Practice run 1 of 3", "Run 1 of 8"
        if step.phase == "training":
            text = protocol.describe_training()
        else:
            text = protocol.describe_trial(step.task or "")
    elif phase == "questions" and step is not None:
        title = "Questions"
        if step.questionnaire not in RUN_QUESTIONNAIRES:
            progress = Progress(0, progress.of)  # about the practice, a break, the whole study
        text = _questions_intro(texts.instructions, step, steps.plan)
        items = tuple(steps.pending_items(step))
    elif phase == "debrief":
        title, text = "Thank you", texts.debrief
    else:
        title, text = "Done", texts.debrief if state.status == "completed" else ""
    if state.paused:
        text = texts.instructions.get("pause", "The session is paused.")
        actions = ()
    return Screen(
        phase=phase,
        title=title,
        text=text.strip(),
        progress=progress,
        items=items,
        actions=actions,
        paused=state.paused,
        questionnaire=step.questionnaire if phase == "questions" and step else None,
        revision=revision,
    )


AFTER_TRAINING_TEXT = "Please answer a few questions about the practice runs you just did."
"""The items' introduction after the practice runs when the protocol has no
``instructions.after_training`` (the after-run text speaks of "the run you just finished")."""


def _questions_intro(instructions: Mapping[str, str], step: Step, plan: Plan) -> str:
    """The text above a page of items: the protocol's for that moment of the session; the
    preference's names the runs it compares by the numbers the participant saw ("Run 3 of 8")
    in ``{first}`` and ``{last}`` (their run numbers, never their condition)."""
    questionnaire = step.questionnaire
    if questionnaire == "after_training":
        return instructions.get("after_training", AFTER_TRAINING_TEXT)
    key = INTRODUCTIONS.get(questionnaire or "", "rating")
    if key == "preference" and key in instructions:
        runs = [plan[i].run_number or 0 for i in step.task_steps] or [0]
        return instructions[key].format(first=runs[0], last=runs[-1])
    return instructions.get(key, instructions["rating"])


def overview(steps: Steps, info: SessionInfo) -> Overview:
    """The experimenter's view: the current step's full condition and the schedule."""
    state, protocol = steps.state, steps.protocol
    step = steps.current()
    run = state.active
    trials = steps.store.trials(session_id=info.session_id)
    attempt = None
    if step is not None and step.kind == "trial":
        attempt = run.attempt if run else steps.next_attempt(step.index)
    task = protocol.task(step.task) if step is not None and step.task else None
    return Overview(
        participant=info.participant,
        session_id=info.session_id,
        status=state.status,
        phase=steps.phase(),
        paused=state.paused,
        step=state.cursor,
        steps=len(steps.plan),
        step_kind=step.kind if step else None,
        training_or_task=step.phase if step else None,
        task=step.task if step else None,
        difficulty=task.difficulty if task else None,
        correctness=task.correctness if task else None,
        mode=step.mode if step else None,
        run=step.run if step else None,
        attempt=attempt,
        trial_id=run.trial_id if run else None,
        trials_completed=sum(t.status == "completed" for t in trials),
        ratings=len(steps.store.ratings(session_id=info.session_id)),
        schedule_row=info.schedule_row,
        group=protocol.group_for(info.schedule_row).label,
        schedule=tuple((a.position, a.task, a.run, a.mode) for a in info.assignments),
        skipped_steps=tuple(sorted(state.skipped)),
        experimenter_actions=experimenter_actions(steps),
    )


def experimenter_actions(steps: Steps) -> tuple[str, ...]:
    """The experimenter actions valid now, in ``EXPERIMENTER_ACTIONS`` order."""
    state = steps.state
    phase = steps.phase()
    if phase == "done":
        return ()
    if phase == "waiting":
        valid = {"start", "withdraw", "end"}
    else:
        valid = {"resume" if state.paused else "pause", "withdraw", "end"}
        step = steps.current()
        if step is not None and step.kind in ("trial", "questions"):
            valid.add("skip")
        try:
            if state.active is not None or steps.redo_target():
                valid.add("redo")
        except SessionStateError:
            pass
    return tuple(a for a in EXPERIMENTER_ACTIONS if a in valid)


__all__ = ["EXPERIMENTER_ACTIONS", "NEEDS_REASON", "experimenter_actions", "overview", "screen"]

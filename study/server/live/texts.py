"""What the participant reads around a run: how it ended, a missed grasp, waiting, a lost tab.

Neutral sentences only: how the run ended, never a condition.
"""

from __future__ import annotations

from study.session import TrialRun

OUTCOME_SENTENCES: dict[str, str] = {
    "success": "You lifted the {target}.",
    "wrong_object": "You lifted the other object, not the {target}.",
    "dropped": "The object slipped out of the gripper, so this run has ended.",
    "knocked_over": "An object was knocked over, so this run has ended.",
    "pushed_off": "An object fell off the table, so this run has ended.",
    "timeout": "Time is up.",
}
"""What the participant reads after a run, ``{target}`` being the object asked for (the
instructions name it already). The three accidents end a run only under ``[control] on_knock =
"end"``; under ``"reset"`` the object is stood up again and the run goes on."""
OTHER_OUTCOME = "The run has ended."
ENDED_BY_EXPERIMENTER = "The experimenter ended this run."
MISSED_GRASP = "Nothing to grasp there: bring the gripper around the object, then close it."
WAIT_TEXT = "Please wait a moment: the experimenter will continue the session."
TAB_LOST_TEXT = "Your run was paused while this page was away. Press Continue when you are ready."
WAITING_TEXT = (
    "Please wait: the experimenter will start your session in a moment."
    " This page will change by itself."
)


def outcome_sentence(run: TrialRun, *, target: str, session_finished: bool) -> str | None:
    """The sentence shown after ``run`` ended: its outcome, "ended by the experimenter" for a
    run aborted by redo or skip, ``None`` when the whole session ended with it."""
    if run.summary is not None:
        return OUTCOME_SENTENCES.get(run.summary.outcome, OTHER_OUTCOME).format(target=target)
    return None if session_finished else ENDED_BY_EXPERIMENTER


__all__ = [
    "ENDED_BY_EXPERIMENTER",
    "MISSED_GRASP",
    "OUTCOME_SENTENCES",
    "TAB_LOST_TEXT",
    "WAITING_TEXT",
    "WAIT_TEXT",
    "outcome_sentence",
]

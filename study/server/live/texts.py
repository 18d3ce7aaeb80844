"""What the participant reads around a run: how it ended, live notices, waiting, a lost tab.

Neutral sentences only: how the run ended, never a condition.
"""

from __future__ import annotations

from study.protocol.model import Texts
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
RUN_FINISHED = "Run finished"
"""The heading of the screen that says how a run ended."""
OTHER_OUTCOME = "The run has ended."
ENDED_BY_EXPERIMENTER = "The experimenter ended this run."
MISSED_GRASP = (
    "The gripper closed on nothing. Move it so that the object is in the middle between the"
    " two fingers, lower it, then close the gripper again."
)
"""Held over the scene for a few seconds after a grasp that caught nothing
(:mod:`study.server.live.notices`): "between the two fingers" alone misled at 3.5 cm off
the mug's middle, where the mug was between them (a tester)."""
MISSED_OFF_CENTRE = (
    "The gripper closed beside the object, not around its middle. Move it {way} until the"
    " object is in the middle, then press G."
)
"""``MISSED_GRASP`` when the hand was down around the object but off its middle along the
fingers as G was pressed: said first (the hand opens where it was, under "not in the
middle"), with why and the key that mends it (``{way}``: :func:`toward_middle`)."""
HELD_ABOVE = (
    "The gripper stays above the object until the object is between its two fingers. Move it"
    " sideways over the middle of the object, then lower it."
)
"""Held while the open gripper is kept above an object it would come down on rather than
around (``app.teleop.guarded_descent``) and the participant's input asks it lower."""

SLIPPED_OUT = (
    "The object slipped out of the gripper. Lower the open gripper around the middle of the"
    " object, then press G again."
)
"""Held over the scene for a few seconds after a grasped object slipped out of the gripper (a
tester saw the mug caught and dropped within 0.16 s, and no word about it); it is put back at
its start pose within a second (``app.trial.accidents``) and the open hand sinks back where it
was, so the scene looks as before G: the notice says what happened and what to do, in a few
words (the 34-word one went unread in its 5 s)."""

SLIPPED_OFF_CENTRE = (
    "The object slipped out: it was not in the middle between the fingers. Move the gripper"
    " {way} until it is, then press G."
)
"""``SLIPPED_OUT`` when the hand was down around the object but off its middle along the
fingers as G was pressed: why it slipped, and the key that mends it (``{way}``:
:func:`toward_middle`; "away or back (W/S)" left the reader to guess which, a tester)."""


def toward_middle(offset_m: float) -> str:
    """The key that takes a hand ``offset_m`` off an object's middle along world x (the
    fingers' length) back toward it, in words: W moves the gripper away (+x), S back."""
    return "back (S)" if offset_m > 0.0 else "away (W)"


SLIPPED_WAITING = (
    "The object slipped out of the gripper. It is put back where it stood once the gripper is"
    " out of the way."
)
"""Held while a dropped object, standing, still waits to be put back a second after the slip
(the gripper is in its spot: a tester who waited with the gripper low saw nothing happen)."""

FELL_OVER = (
    "An object fell over. It is put back where it stood as soon as the gripper is out of the"
    " way there."
)
"""Held while an object knocked over or off the table waits to be put back (``on_knock =
"reset"``): a tester's mug lay 29 s without a word while the gripper hovered over its spot."""

AS_LOW_AS_IT_GOES = (
    "The gripper is as low as it goes here. If the object is between the two fingers, press G"
    " to close the gripper."
)
"""Held while the open gripper, lowered around an object, is kept from putting its palm on the
object's top (``app.teleop.guarded_descent``) and the participant's input asks it lower."""

NOT_CENTRED = (
    "The gripper is as low as it goes, but the object is not in the middle between the fingers."
    " Move the gripper away or back (W/S) until it is, then press G."
)
"""Held instead of ``AS_LOW_AS_IT_GOES`` while the hand, as low as it goes around an object, is
off its middle along the fingers: closed there the fingers squeeze the object away (a tester:
5 of 5 grasps 0.9-3.1 cm off failed after the "press G" notice). Said with the one key that
mends it when the hand is off along the fingers (``not_centred``)."""


def not_centred(offset_m: float, *, centred_m: float) -> str:
    """``NOT_CENTRED`` for a hand ``offset_m`` off the object's middle along world x: the one
    key that mends it when more than ``centred_m`` (a tester read "back (S)" after a failed
    grasp, then "away or back (W/S)" for the same hand), else both."""
    if abs(offset_m) <= centred_m:
        return NOT_CENTRED
    return NOT_CENTRED.replace("away or back (W/S)", toward_middle(offset_m))


RESTING_ON_OBJECT = (
    "A finger is resting on the object, so the gripper cannot go lower here. Move the gripper"
    " sideways until the object is between the two fingers, then lower it."
)
"""Held while a finger rests on an object and the participant's input asks the gripper lower
(on a mug's rim it sits still: the keys seemed to do nothing)."""
WAIT_TEXT = "Please wait a moment: the experimenter will continue the session."
TAB_LOST_TEXT = "Your run was paused while this page was away. Press Continue when you are ready."
WAITING_TEXT = (
    "Please wait: the experimenter will start your session in a moment."
    " This page will change by itself."
)
AT_REACH_LIMIT = (
    "The handle and the keys move the gripper only inside the frame drawn on the table."
)
"""Shown while the participant's input is held past the reach (handle or keys). It says what
the input can do, not what the arm can: at the reach's edge (the hard task) the robot's help
carries the gripper past the frame, which "the arm cannot reach beyond" would deny."""
TIME_WARNING_S = 10.0
TIME_WARNING = "10 seconds left in this run."

CLOSE_TEXT = "You may close this page now."
REDIRECT_DELAY_S = 8
"""Seconds the end screen shows the completion code before the page goes back to the
recruitment site by itself (the participant may press Continue sooner)."""
LINK_INVALID_TEXT = (
    "This link is missing what the study needs to know. Please open the study again from the"
    " page where you found it (for example your study page on the recruitment site)."
)
LINK_CLOSED_TEXT = (
    "The study is not taking new participants at the moment; its places may all be taken."
    " Please close this page and, if you came from a recruitment site, return the study there."
    " Thank you for your interest."
)
LINK_FAILED_TEXT = (
    "The study could not open your session just now. Please reload this page in a minute;"
    " nothing you did is lost."
)
LINK_IN_USE_TEXT = (
    "The study is already open in another tab or window. Please go on there and close this"
    " one. If you closed the other one, this page goes on by itself in a moment."
)


def end_screen(status: str, texts: Texts) -> tuple[str, str, str | None]:
    """``(title, text, redirect URL or None)`` of the page once the session is over: after a
    completed session the debrief, the protocol's completion code and the way back to the
    recruitment site (``redirect_url``); otherwise that the session has ended."""
    if status != "completed":
        return "Done", f"The session has ended. Thank you. {CLOSE_TEXT}", None
    parts = [texts.debrief.strip()] if texts.debrief.strip() else ["Thank you."]
    if texts.completion_code:
        parts.append(
            f"Your completion code is **{texts.completion_code}**. Please copy it now, in case"
            " the recruitment site asks for it."
        )
    if texts.redirect_url:
        parts.append(
            f"This page takes you back to the recruitment site in {REDIRECT_DELAY_S} seconds;"
            " press Continue to go now."
        )
        return "Done", "\n\n".join(parts), texts.redirect_url
    parts.append(CLOSE_TEXT)
    return "Done", "\n\n".join(parts), None


def outcome_sentence(run: TrialRun, *, target: str, session_finished: bool) -> str | None:
    """The sentence shown after ``run`` ended: its outcome, "ended by the experimenter" for a
    run aborted by redo or skip, ``None`` when the whole session ended with it."""
    if run.summary is not None:
        return OUTCOME_SENTENCES.get(run.summary.outcome, OTHER_OUTCOME).format(target=target)
    return None if session_finished else ENDED_BY_EXPERIMENTER


__all__ = [
    "AS_LOW_AS_IT_GOES",
    "AT_REACH_LIMIT",
    "CLOSE_TEXT",
    "ENDED_BY_EXPERIMENTER",
    "FELL_OVER",
    "HELD_ABOVE",
    "LINK_CLOSED_TEXT",
    "LINK_FAILED_TEXT",
    "LINK_INVALID_TEXT",
    "LINK_IN_USE_TEXT",
    "MISSED_GRASP",
    "MISSED_OFF_CENTRE",
    "NOT_CENTRED",
    "OUTCOME_SENTENCES",
    "RESTING_ON_OBJECT",
    "RUN_FINISHED",
    "SLIPPED_OFF_CENTRE",
    "SLIPPED_OUT",
    "SLIPPED_WAITING",
    "TAB_LOST_TEXT",
    "TIME_WARNING",
    "TIME_WARNING_S",
    "WAITING_TEXT",
    "WAIT_TEXT",
    "end_screen",
    "not_centred",
    "outcome_sentence",
    "toward_middle",
]

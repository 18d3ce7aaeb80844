"""The parts of a protocol as typed, immutable values (the whole: ``study.protocol.Protocol``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any


@dataclass(frozen=True)
class StudyInfo:
    """Identity of the study: ``id`` is stored with every session; ``participants`` is the
    planned sample size (a whole number of balanced schedule cycles), if given."""

    id: str
    title: str
    version: str
    description: str = ""
    participants: int | None = None


@dataclass(frozen=True)
class Control:
    """Settings shared by every trial: ``1 / rate_hz`` must be a whole number of ``physics_dt``.

    ``on_knock``: ``reset`` (a knocked-over or fallen object is stood up again and the run goes
    on) or ``end`` (the accident ends the run); ``app.trial.accidents``. ``input_mapping``:
    ``absolute`` (the handle and keys place the gripper's target) or ``relative`` (they move the
    gripper from where it is: a robot pulling elsewhere must be countered);
    ``app.teleop.participant_input``. Both are the interface, not a condition.
    """

    rate_hz: float
    physics_dt: float
    time_limit_s: float
    lift_height_m: float
    on_knock: str = "reset"
    input_mapping: str = "absolute"


@dataclass(frozen=True)
class Task:
    """One task type: a cell of the task factors (the paper's difficulty x correctness), done
    once in every mode. ``levels`` maps each task factor to this task's level; ``prediction`` is
    the predictor table the robot uses in it."""

    name: str
    scene: str
    time_limit_s: float
    prediction: Mapping[str, Any]
    levels: Mapping[str, str] = field(default_factory=dict)

    @property
    def difficulty(self) -> str | None:
        """The paper's difficulty level (None when the protocol has no such factor)."""
        return self.levels.get("difficulty")

    @property
    def correctness(self) -> str | None:
        """The paper's correctness level (None when the protocol has no such factor)."""
        return self.levels.get("correctness")


INTENT_DISPLAYS = ("none", "goal")
"""What the participant page shows of the robot's intent: ``none``, or ``goal``: a neutral ring
on the table around the object the robot predicts, its opacity following the robot's confidence
(``study.server.intent_cue``)."""


@dataclass(frozen=True)
class Mode:
    """How the robot helps in a run: a level of ``mode`` (the arbitration; ``None`` =
    unassisted), crossed with the levels of any other within factor that sets how runs go.

    ``levels`` maps each of those factors to this mode's level (``{"mode": name}`` in the
    paper). ``intent``: one of :data:`INTENT_DISPLAYS`. ``confidence``, ``policy``,
    ``input_mapping`` and ``latency_s`` override the protocol's when set.
    """

    name: str
    arbitration: Mapping[str, Any] | None
    confidence: Mapping[str, Any] | None = None  # overrides the protocol's [confidence]
    intent: str = "none"
    levels: Mapping[str, str] = field(default_factory=dict)
    policy: Mapping[str, Any] | None = None
    input_mapping: str | None = None
    latency_s: float | None = None  # added latency (app.teleop.delayed_input)


@dataclass(frozen=True)
class Group:
    """One between-subjects cell: a level of every between factor (``levels``) and the run
    settings they set (``settings``: confidence, policy, intent, input_mapping ...). A
    protocol without between factors has one group, ``""``, that sets nothing."""

    name: str
    levels: Mapping[str, str] = field(default_factory=dict)
    settings: Mapping[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """``mapping=relative``: the group's levels by factor, for the experimenter ("" when
        the protocol has no between factor)."""
        return ", ".join(f"{f}={level}" for f, level in self.levels.items())


@dataclass(frozen=True)
class Training:
    """Unassisted practice runs before the tasks (covariates: skill and baseline rating)."""

    runs: int
    scene: str
    time_limit_s: float
    prediction: Mapping[str, Any]


@dataclass(frozen=True)
class Texts:
    """Participant-facing text; none of it may name a condition (checked on load).

    ``instructions`` maps a phase (``welcome``, ``training``, ``task``, ``rating``,
    ``preference``, ``pause``, ``after_training``) to its text; ``{target}`` in the training and
    task texts is replaced by the target object's name, ``{first}`` and ``{last}`` in the
    preference text by the numbers of the runs it compares. ``completion_code`` (shown at the
    end of a completed session) and ``redirect_url`` (where the page then goes: an online
    panel's completion URL) are for online studies; empty when not used. ``consent_online`` and
    ``debrief_online`` are what a participant who came by the open link reads instead (no
    experimenter to ask); empty: the same texts as in the lab (:meth:`for_link`).
    """

    consent: str
    consent_agree: str
    debrief: str
    instructions: Mapping[str, str]
    completion_code: str = ""
    redirect_url: str = ""
    consent_online: str = ""
    debrief_online: str = ""

    def for_link(self) -> Texts:
        """The texts a participant who came by the open link reads: the online consent and
        debrief where the protocol gives them."""
        return replace(
            self,
            consent=self.consent_online or self.consent,
            debrief=self.debrief_online or self.debrief,
        )

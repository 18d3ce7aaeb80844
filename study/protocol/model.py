"""The parts of a protocol as typed, immutable values (the whole: ``study.protocol.Protocol``)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
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
    """Timing shared by every trial: ``1 / rate_hz`` must be a whole number of ``physics_dt``."""

    rate_hz: float
    physics_dt: float
    time_limit_s: float
    lift_height_m: float


@dataclass(frozen=True)
class Task:
    """One task type: a cell of difficulty x correctness, done once in every mode."""

    name: str
    difficulty: str
    correctness: str
    scene: str
    time_limit_s: float


INTENT_DISPLAYS = ("none", "goal")
"""What the participant page shows of the robot's intent: ``none``, or ``goal``: a neutral ring
on the table around the object the robot predicts, its opacity following the robot's confidence
(``study.server.intent_cue``)."""


@dataclass(frozen=True)
class Mode:
    """One level of the within-task factor (the arbitration); ``arbitration`` None = unassisted.

    ``intent``: one of :data:`INTENT_DISPLAYS`; two modes that differ only in it make intent
    display a level of the mode factor, balanced by the same Williams square."""

    name: str
    arbitration: Mapping[str, Any] | None
    confidence: Mapping[str, Any] | None = None  # overrides the protocol's [confidence]
    intent: str = "none"


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
    ``preference``, ``pause``) to its text; ``{target}`` in the training and task texts is replaced
    by the target object's name. ``completion_code`` (shown at the end of a completed session)
    and ``redirect_url`` (where the page then goes: an online panel's completion URL) are for
    online studies; empty when not used.
    """

    consent: str
    consent_agree: str
    debrief: str
    instructions: Mapping[str, str]
    completion_code: str = ""
    redirect_url: str = ""

"""Typed rows read back from the store (one dataclass per table)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class StoreMeta:
    """The ``schema_version`` row: which schema and which protocol wrote the file."""

    version: int
    protocol_id: str
    protocol_version: str
    protocol_hash: str
    created_at: str


@dataclass(frozen=True, slots=True)
class ParticipantRecord:
    participant: str
    enrolled_at: str
    schedule_row: int


@dataclass(frozen=True, slots=True)
class SessionRecord:
    """A participant's session. ``cursor`` indexes the session plan (see ``study.session.plan``);
    ``status`` is one of ``enrolled``, ``running``, ``completed``, ``withdrawn``, ``ended``."""

    session_id: int
    participant: str
    created_at: str
    ended_at: str | None
    status: str
    cursor: int
    seed: int


@dataclass(frozen=True, slots=True)
class AssignmentRecord:
    """One task run of the participant's schedule: ``position`` is 1-based among task trials,
    ``run`` is ``"first"`` or ``"second"`` within the task."""

    participant: str
    position: int
    task: str
    run: str
    mode: str
    schedule_row: int


@dataclass(frozen=True, slots=True)
class TrialRecord:
    """One trial attempt. ``status``: ``running`` (only while a process runs it), ``completed``,
    ``redone``, ``skipped`` or ``interrupted``; ``duration_s`` excludes pauses."""

    trial_id: int
    session_id: int
    participant: str
    step: int
    trial_number: int
    phase: str
    position: int | None
    task: str | None
    difficulty: str | None
    correctness: str | None
    mode: str
    run: str | None
    attempt: int
    status: str
    outcome: str | None
    success: bool | None
    duration_s: float | None
    ticks: int
    seed: int
    started_at: str
    ended_at: str | None
    goal_names: list[str]
    goal_positions: list[list[float]]
    target: str | None
    note: str | None


@dataclass(frozen=True, slots=True)
class RatingRecord:
    rating_id: int
    session_id: int
    participant: str
    step: int
    phase: str
    task: str | None
    mode: str | None
    run: str | None
    trial_id: int | None
    item: str
    value: int
    answered_at: str


@dataclass(frozen=True, slots=True)
class AnswerRecord:
    """An answer to a non-Likert item (``study.protocol.questionnaire``): ``value`` is the
    option or text as given (``None``: an optional item left empty); ``number`` the value of a
    number item."""

    answer_id: int
    session_id: int
    participant: str
    step: int
    questionnaire: str
    item: str
    kind: str
    value: str | None
    number: float | None
    answered_at: str


@dataclass(frozen=True, slots=True)
class EventRecord:
    event_id: int
    session_id: int | None
    participant: str | None
    at: str
    kind: str
    detail: dict[str, Any]


@dataclass(frozen=True, slots=True)
class Lease:
    """Proof that this process holds a participant's session (see ``Store.acquire_lease``).
    ``took_over`` describes the stale holder replaced, if any."""

    participant: str
    token: str
    pid: int
    took_over: dict[str, Any] | None = None

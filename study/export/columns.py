"""The columns of the tidy tables, in order (``study.codebook`` describes each one)."""

from __future__ import annotations

from collections.abc import Sequence

from app.trial.accidents import ACCIDENT_MEASURES

TABLE_NAMES = ("trials", "samples", "ratings", "answers", "participants", "events", "sessions")

DEFAULT_POINTS = 7

TRIAL_COLUMNS = (
    "participant",
    "session_id",
    "phase",
    "schedule_row",
    "position",
    "task",
    "difficulty",
    "correctness",
    "mode",
    "run",
    "attempt",
    "status",
    "outcome",
    "success",
    "duration_s",
    "ticks",
    "contacts",
    "contact_impulse_ns",
    *ACCIDENT_MEASURES,
    "started_at",
    "goal_names",
    "goal_positions",
    "target",
    "training_time_s",
    "baseline_rating",
    "tasks_completed",
)
"""Fixed leading columns of ``trials`` for the paper's factors; Likert and preference columns and
``trial_id`` follow. Another protocol's factors take the place of ``difficulty``, ``correctness``
and ``mode`` (:func:`trial_columns`)."""

PAPER_FACTORS = ("difficulty", "correctness", "mode")


def trial_columns(factors: Sequence[str] | None) -> tuple[str, ...]:
    """The leading columns of ``trials`` with one column per declared factor, in the protocol's
    order, where the paper's three stand (``None``: the paper's columns)."""
    if factors is None:
        return TRIAL_COLUMNS
    at = TRIAL_COLUMNS.index(PAPER_FACTORS[0])
    rest = TRIAL_COLUMNS[at + len(PAPER_FACTORS) :]
    return (*TRIAL_COLUMNS[:at], *factors, *rest)


SAMPLE_KEY = ("trial_id", "participant", "tick")
"""Leading columns of ``samples``; the store's sample columns (``app.trial.samples``) follow,
``predicted`` as the goal's name and ``probabilities`` spread over ``prob_<k>``."""

RATING_COLUMNS = (
    "participant",
    "session_id",
    "phase",
    "task",
    "mode",
    "run",
    "item",
    "value",
    "answered_at",
    "trial_id",
)

ANSWER_COLUMNS = (
    "participant",
    "session_id",
    "questionnaire",
    "item",
    "kind",
    "value",
    "number",
    "option",
    "correct",
    "answered_at",
)

PARTICIPANT_COLUMNS = (
    "participant",
    "session_id",
    "schedule_row",
    "status",
    "enrolled_at",
    "included",
    "excluded_because",
    "retention",
    "attention_checks",
    "attention_failures",
)
"""Fixed leading columns of ``participants``; one column per item asked once per participant
(demographics, the comment: its answer) follows."""

EVENT_COLUMNS = ("participant", "session_id", "at", "kind", "detail")

RECRUITMENT_COLUMNS: dict[str, str] = {
    "PROLIFIC_PID": "prolific_pid",
    "STUDY_ID": "prolific_study_id",
    "SESSION_ID": "prolific_session_id",
    "pid": "pid",
}
"""An open link's URL parameters (``study.server.recruitment``) -> their ``sessions`` column."""

SESSION_COLUMNS = (
    "participant",
    "session_id",
    "schedule_row",
    "status",
    "enrolled_at",
    "started_at",
    "ended_at",
    "source",
    *RECRUITMENT_COLUMNS.values(),
)


def participant_item_column(item: str) -> str:
    """The ``participants`` column of an item asked once (``item_<id>`` if the id is one of
    the table's fixed column names)."""
    return f"item_{item}" if item in PARTICIPANT_COLUMNS else item

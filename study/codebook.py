"""The codebook: one row per column of every tidy table, saying what it holds.

``codebook(tables, protocol=None)`` describes exactly the columns present (dynamic ones too:
``prob_<k>``, one column per Likert item, ``preference_<mode>``, one ``participants`` column per
item asked once); with the protocol, item columns carry their prompt and anchors, options,
range or length. ``write_codebook`` writes ``codebook.csv`` and
``codebook.md``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from app.trial.accidents import ACCIDENT_MEASURES
from app.trial.samples import SAMPLE_DOCS
from study.errors import StudyError
from study.protocol.questionnaire import ChoiceItem, NumberItem, TextItem

if TYPE_CHECKING:
    from study.protocol import Protocol

CODEBOOK_COLUMNS = ("table", "column", "dtype", "description", "values")

FIXED: dict[str, dict[str, tuple[str, str]]] = {
    "trials": {
        "participant": ("participant id (pseudonymous)", ""),
        "session_id": ("the participant's session in the store", ""),
        "phase": ("training (unassisted practice) or task", "training | task"),
        "schedule_row": ("design row of the counterbalanced schedule (study.schedule)", ">= 0"),
        "position": (
            "1-based position among the participant's task trials (empty for training)",
            "1..tasks x modes",
        ),
        "task": ("task type (condition id; empty for training)", ""),
        "difficulty": ("manipulated factor: difficulty of the task", ""),
        "correctness": ("manipulated factor: prediction correctness", ""),
        "mode": ("manipulated factor: arbitration mode; none for unassisted training", ""),
        "run": ("which run of the task this is", "first | second | ..."),
        "attempt": ("attempt number of this trial step (a redo starts attempt 2)", "1.."),
        "status": (
            "what became of the attempt (running: its process was still running it at "
            "export; one whose process had died is reported interrupted)",
            "completed | redone | skipped | interrupted | running",
        ),
        "outcome": (
            "how the trial ended; the accidents (dropped: a held object slipped out of the"
            " gripper; knocked_over: an object was knocked over, never grasped; pushed_off: an"
            " object fell off the table) end a run only under [control] on_knock = end (under"
            " reset, the default, the object is stood up again and the run goes on: see"
            " knocks, pushes_off, drops)",
            "success | wrong_object | dropped | knocked_over | pushed_off | timeout | aborted"
            " | interrupted",
        ),
        "success": ("the target was lifted", "true | false"),
        "duration_s": ("time to complete, seconds, pauses excluded", "s"),
        "ticks": ("control ticks run (rows in samples)", ""),
        "contacts": (
            "dependent measure: touches of the arm (wrist, hand, fingers) on objects"
            " in the trial; the fingers closing on an object in a grasp do not count",
            "0..",
        ),
        "contact_impulse_ns": ("dependent measure: total normal impulse of those touches", "N s"),
        **{
            name: (f"dependent measure beside time: {text}, from the trial's events", "0..")
            for name, text in ACCIDENT_MEASURES.items()
        },
        "started_at": ("start time, ISO 8601 UTC", ""),
        "goal_names": ("JSON list of the scene's goal names; prob_<k> follows this order", ""),
        "goal_positions": ("JSON list of [x, y, z] goal positions, metres, world frame", "m"),
        "target": ("the goal the participant was asked to pick up", ""),
        "training_time_s": (
            "covariate initial skill: mean duration_s of the participant's completed training runs",
            "s",
        ),
        "baseline_rating": (
            "covariate rating without assistance: mean of the participant's after-training ratings",
            "1..points",
        ),
        "tasks_completed": ("covariate learning: task trials completed before this one", "0.."),
        "trial_id": ("trial attempt id (joins samples and ratings)", ""),
    },
    "samples": {
        "trial_id": ("trial attempt id (joins trials)", ""),
        "participant": ("participant id", ""),
        "tick": ("control tick, 0-based", ""),
        "predicted": ("name of the goal the robot predicts", ""),  # the store keeps its index
        # every other samples column is described where it is declared: app.trial.samples
    },
    "ratings": {
        "participant": ("participant id", ""),
        "session_id": ("the participant's session in the store", ""),
        "phase": (
            "training (rating of the unassisted robot), task, or session (an item asked once)",
            "training | task | session",
        ),
        "task": ("task type the rating is about (empty after training)", ""),
        "mode": ("mode of the rated run; empty for a preference between runs", ""),
        "run": ("which run of the task was rated; empty for a preference", "first | second"),
        "item": ("questionnaire item id", ""),
        "value": ("the answer, 1..points (1 = the first anchor)", "1..points"),
        "answered_at": ("time of the answer, ISO 8601 UTC", ""),
        "trial_id": ("the rated trial attempt, if the rating is about one", ""),
    },
    "answers": {
        "participant": ("participant id", ""),
        "session_id": ("the participant's session in the store", ""),
        "questionnaire": (
            "when the item was asked; recorded: a retention answer the experimenter recorded"
            " after the session stopped (python -m study retention)",
            "before_training | between_tasks | closing | recorded",
        ),
        "item": ("questionnaire item id (the protocol's [questionnaire.items.<id>])", ""),
        "kind": ("the item's kind", "choice | attention | retention | number | text"),
        "value": (
            "the answer as given: the option's text, the number as typed and read, or the free"
            " text (trimmed); empty: an optional item left empty",
            "",
        ),
        "number": ("the answer of a number item, in the item's unit", ""),
        "option": ("a choice's 1-based position among the item's options", "1.."),
        "correct": ("an attention check answered with its correct option", "true | false"),
        "answered_at": ("time of the answer, ISO 8601 UTC", ""),
    },
    "participants": {
        "participant": ("participant id (pseudonymous)", ""),
        "session_id": ("the participant's session in the store", ""),
        "schedule_row": ("design row of the counterbalanced schedule (study.schedule)", ">= 0"),
        "status": (
            "how the session stands",
            "enrolled | running | completed | withdrawn | ended",
        ),
        "enrolled_at": ("enrolment time, ISO 8601 UTC", ""),
        "included": (
            "the participant's data are in the other tables: they agreed to keeping them (or"
            " the protocol asks no data-retention question)",
            "true | false",
        ),
        "excluded_because": ("why an excluded participant's data are left out", ""),
        "retention": ("the answer to the data-retention question, as given", ""),
        "attention_checks": ("attention-check items answered", "0.."),
        "attention_failures": ("attention checks answered with another option", "0.."),
    },
    "events": {
        "participant": ("participant id (empty for store-wide events)", ""),
        "session_id": ("the session the event belongs to (empty for store-wide events)", ""),
        "at": ("time, ISO 8601 UTC", ""),
        "kind": ("event kind (enrol, consent, trial_start, trial_end, answer, redo, ...)", ""),
        "detail": ("JSON object with the event's details", ""),
    },
    "sessions": {
        "participant": ("participant id (pseudonymous; L0001... for the open link's)", ""),
        "session_id": ("the participant's session in the store", ""),
        "schedule_row": ("design row of the counterbalanced schedule (study.schedule)", ">= 0"),
        "status": (
            "what became of the session",
            "enrolled | running | completed | withdrawn | ended",
        ),
        "enrolled_at": ("enrolment time, ISO 8601 UTC", ""),
        "started_at": ("first start of the session, ISO 8601 UTC (empty: never started)", ""),
        "ended_at": ("time the session completed, was withdrawn or ended, ISO 8601 UTC", ""),
        "source": (
            "how the participant came: enrolled in the console, or by the open link",
            "console | link",
        ),
        "prolific_pid": (
            "recruitment ID: the link's PROLIFIC_PID (identifies the panel account: remove"
            " before sharing the data)",
            "",
        ),
        "prolific_study_id": ("the link's STUDY_ID (the panel's study)", ""),
        "prolific_session_id": ("the link's SESSION_ID (the panel's submission)", ""),
        "pid": (
            "recruitment ID: the link's generic pid (remove before sharing the data)",
            "",
        ),
    },
}


class CodebookError(StudyError, ValueError):
    """A table column has no codebook entry (add one here when adding a column)."""


def _describe(
    table: str, column: str, protocol: Protocol | None, columns: list[str]
) -> tuple[str, str]:
    fixed = FIXED.get(table, {})
    if column in fixed:
        return fixed[column]
    if table == "samples" and column in SAMPLE_DOCS:
        return SAMPLE_DOCS[column]
    m = re.fullmatch(r"prob_(\d+)", column)
    if table == "samples" and m:
        return (
            f"P(goal {m.group(1)} | trajectory so far): the robot's probability of the"
            f" goal at index {m.group(1)} of the trial's goal_names",
            "0..1",
        )
    if table in ("trials", "participants") and protocol is not None and column in protocol.factors:
        if column in protocol.between_factors:
            where = "the participant's level" + (
                " on every row, practice included" if table == "trials" else ""
            )
            return (
                f"manipulated factor: {column} (between subjects; {where})",
                " | ".join(protocol.factors[column]),
            )
        return (
            f"manipulated factor: {column} (within subjects; empty for practice runs)",
            " | ".join(protocol.factors[column]),
        )
    if table == "trials":
        return _likert(column, protocol, columns)
    if table == "participants":
        return _once_item(column, protocol)
    raise CodebookError(f"no codebook entry for column {column!r} of table {table!r}")


def _likert(column: str, protocol: Protocol | None, columns: list[str]) -> tuple[str, str]:
    """Per-run Likert items, the task preference and its re-centred ``<item>_<mode>`` form."""
    q = protocol.questionnaire if protocol is not None else None
    for base in columns:
        if (
            base != column
            and column.startswith(base + "_")
            and base not in FIXED["trials"]
            and (q is None or base in q.items)
        ):
            mode = column[len(base) + 1 :]
            half = ((q.items[base].scale.points if q else 7) - 1) / 2
            return (
                f"{base} re-centred on mode {mode}: positive = preferred the {mode} run,"
                " negative = preferred the other run, 0 = no preference",
                f"{-half:g}..{half:+g}",
            )
    if q is None:
        return (
            f"Likert answer to item {column!r}: a rating of this run, or the task's"
            " preference between its two runs (then on both runs)",
            "1..7",
        )
    if column not in q.items:
        raise CodebookError(f"no codebook entry for column {column!r} of table 'trials'")
    item = q.items[column]
    if item in q.after_task:
        text = f'preference between the task\'s two runs, "{item.prompt}"; raw answer, on both runs'
    else:
        text = f'Likert rating of this run, asked after it: "{item.prompt}"'
    return text, "; ".join(f"{i} = {a}" for i, a in enumerate(item.scale.anchors, 1))


def _once_item(column: str, protocol: Protocol | None) -> tuple[str, str]:
    """A ``participants`` column holding the answer to an item asked once."""
    if protocol is None:
        return f"answer to the questionnaire item {column!r}", ""
    items = protocol.questionnaire.items
    item = items.get(column) or items.get(column.removeprefix("item_"))
    if item is None:
        raise CodebookError(f"no codebook entry for column {column!r} of table 'participants'")
    text = f'answer to "{item.prompt}"'
    if isinstance(item, ChoiceItem):
        return text, " | ".join(item.options)
    if isinstance(item, NumberItem):
        return text + (f" ({item.unit})" if item.unit else ""), item.range_text()
    if isinstance(item, TextItem):
        return text + " (free text; empty: left empty)", f"at most {item.max_length} characters"
    return text, ""


def codebook(
    tables: Mapping[str, pd.DataFrame], *, protocol: Protocol | None = None
) -> pd.DataFrame:
    """One row per (table, column) of ``tables``, in table and column order."""
    rows = []
    for table, df in tables.items():
        for column in df.columns:
            description, values = _describe(table, column, protocol, list(df.columns))
            rows.append((table, column, str(df[column].dtype), description, values))
    return pd.DataFrame(rows, columns=list(CODEBOOK_COLUMNS))


def write_codebook(book: pd.DataFrame, out: str | os.PathLike[str]) -> list[Path]:
    """Write ``codebook.csv`` and ``codebook.md`` (one Markdown table per data table)."""
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / "codebook.csv"
    book.to_csv(csv_path, index=False)
    lines = [
        "# Codebook",
        "",
        "Tidy long-format tables exported by `python -m study export`; one row per trial"
        " attempt (trials), control tick (samples), rating (ratings), other answer (answers),"
        " participant (participants), event (events) or participant's session (sessions).",
        "",
    ]
    for table, group in book.groupby("table", sort=False):
        lines += [
            f"## {table}",
            "",
            "| column | type | description | values |",
            "|---|---|---|---|",
        ]
        for r in group.itertuples(index=False):
            cells = [f"`{r.column}`", r.dtype, r.description, r.values]
            lines.append("| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |")
        lines.append("")
    md_path = out_dir / "codebook.md"
    md_path.write_text("\n".join(lines))
    return [csv_path, md_path]

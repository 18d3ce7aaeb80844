"""The store's SQLite schema, version ``SCHEMA_VERSION``.

One row in ``schema_version`` says which schema and which protocol (study id + content hash)
wrote the file; ``protocols`` keeps that protocol's full TOML text keyed by its content hash, so
the exact study definition can be rebuilt from the store alone. Demographics live in their own table, apart from trial data. ``samples`` holds
one row per control tick, keyed by ``(trial_id, tick)``, with the columns ``app.trial.samples``
declares (the 7-vectors spread over ``q1..q7`` etc. so the file stays readable with any SQLite
client). Sample columns are matched by name: a declared column an older file lacks is added when
it is opened read-write and read as ``NULL`` when it is opened read-only (no version change).
"""

from __future__ import annotations

from app.trial import samples as layout

SCHEMA_VERSION = 3
"""Version 2 added the ``protocols`` table, version 3 the ``answers`` table (questionnaire
answers other than ratings: choices, numbers, free text, attention checks, the data-retention
answer). An older file is read as it is (no stored protocol text, no answers) and upgraded when
opened read-write (``MIGRATIONS``). Older software refuses a version-3 file rather than export
it without its answers, which may exclude participants who declined to have their data kept."""

READABLE_VERSIONS = (1, 2, 3)

PROTOCOLS_DDL = """
CREATE TABLE protocols (
    content_hash TEXT PRIMARY KEY,
    protocol_id TEXT NOT NULL,
    protocol_version TEXT NOT NULL,
    text TEXT NOT NULL,
    recorded_at TEXT NOT NULL
)"""

ANSWERS_DDL = """
CREATE TABLE answers (
    answer_id INTEGER PRIMARY KEY,
    session_id INTEGER NOT NULL REFERENCES sessions(session_id),
    participant TEXT NOT NULL REFERENCES participants(participant),
    step INTEGER NOT NULL,
    questionnaire TEXT NOT NULL,
    item TEXT NOT NULL,
    kind TEXT NOT NULL,
    value TEXT,
    number REAL,
    answered_at TEXT NOT NULL,
    UNIQUE (session_id, step, item)
)"""
ANSWER_COLUMNS = (
    "answer_id",
    "session_id",
    "participant",
    "step",
    "questionnaire",
    "item",
    "kind",
    "value",
    "number",
    "answered_at",
)
"""One row per answer to a non-Likert item: ``value`` is the option or text as given (NULL:
an optional item left empty), ``number`` the value of a number item."""

MIGRATIONS: dict[int, tuple[str, ...]] = {1: (PROTOCOLS_DDL,), 2: (ANSWERS_DDL,)}
"""``{from_version: statements}`` that bring a file to ``from_version + 1``."""

SAMPLE_KEY = ("trial_id", "tick")
"""A sample row's key: the trial and its control tick (0-based, in the order stored)."""

SAMPLE_COLUMNS: tuple[str, ...] = (*SAMPLE_KEY, *layout.SAMPLE_COLUMNS)
"""Column order of a sample row: the key, then the data columns ``app.trial.samples``
declares (``predicted`` is the goal index; ``probabilities`` and ``events`` are JSON lists)."""

SAMPLE_TYPES: dict[str, str] = {
    c: layout.SQL_TYPES[f.kind] for f in layout.SAMPLE_FIELDS for c in f.columns
}
"""SQLite type of each data column of a new store."""

ADDED_SAMPLE_TYPES: dict[str, str] = {
    c: layout.ADDED_SQL_TYPES[f.kind] for f in layout.SAMPLE_FIELDS for c in f.columns
}
"""SQLite type of a data column added to an existing store (``opening.add_sample_columns``)."""

_SAMPLE_DDL = ",\n    ".join(
    [
        "trial_id INTEGER NOT NULL REFERENCES trials(trial_id)",
        "tick INTEGER NOT NULL",
        # the REAL columns first, as in every store written so far (for ``SELECT *`` readers)
        *sorted((f"{c} {t}" for c, t in SAMPLE_TYPES.items()), key=lambda d: " REAL" not in d),
        "PRIMARY KEY (trial_id, tick)",
    ]
)

DDL = f"""
CREATE TABLE schema_version (
    version INTEGER NOT NULL,
    protocol_id TEXT NOT NULL,
    protocol_version TEXT NOT NULL,
    protocol_hash TEXT NOT NULL,
    created_at TEXT NOT NULL
);
{PROTOCOLS_DDL};
CREATE TABLE participants (
    participant TEXT PRIMARY KEY,
    enrolled_at TEXT NOT NULL,
    schedule_row INTEGER NOT NULL
);
CREATE TABLE demographics (
    participant TEXT PRIMARY KEY REFERENCES participants(participant),
    recorded_at TEXT NOT NULL,
    data TEXT NOT NULL
);
CREATE TABLE sessions (
    session_id INTEGER PRIMARY KEY,
    participant TEXT NOT NULL UNIQUE REFERENCES participants(participant),
    created_at TEXT NOT NULL,
    ended_at TEXT,
    status TEXT NOT NULL,
    cursor INTEGER NOT NULL DEFAULT 0,
    seed INTEGER NOT NULL
);
CREATE TABLE assignments (
    participant TEXT NOT NULL REFERENCES participants(participant),
    position INTEGER NOT NULL,
    task TEXT NOT NULL,
    run TEXT NOT NULL,
    mode TEXT NOT NULL,
    schedule_row INTEGER NOT NULL,
    PRIMARY KEY (participant, position)
);
CREATE TABLE leases (
    participant TEXT PRIMARY KEY REFERENCES participants(participant),
    token TEXT NOT NULL,
    pid INTEGER NOT NULL,
    host TEXT NOT NULL,
    process_start TEXT NOT NULL,
    acquired_at TEXT NOT NULL,
    heartbeat_at REAL NOT NULL
);
CREATE TABLE trials (
    trial_id INTEGER PRIMARY KEY,
    session_id INTEGER NOT NULL REFERENCES sessions(session_id),
    participant TEXT NOT NULL REFERENCES participants(participant),
    step INTEGER NOT NULL,
    trial_number INTEGER NOT NULL,
    phase TEXT NOT NULL,
    position INTEGER,
    task TEXT,
    difficulty TEXT,
    correctness TEXT,
    mode TEXT NOT NULL,
    run TEXT,
    attempt INTEGER NOT NULL,
    status TEXT NOT NULL,
    outcome TEXT,
    success INTEGER,
    duration_s REAL,
    ticks INTEGER NOT NULL DEFAULT 0,
    seed INTEGER NOT NULL,
    started_at TEXT NOT NULL,
    ended_at TEXT,
    goal_names TEXT NOT NULL,
    goal_positions TEXT NOT NULL,
    target TEXT,
    note TEXT,
    UNIQUE (session_id, step, attempt)
);
CREATE TABLE samples (
    {_SAMPLE_DDL}
) WITHOUT ROWID;
CREATE TABLE ratings (
    rating_id INTEGER PRIMARY KEY,
    session_id INTEGER NOT NULL REFERENCES sessions(session_id),
    participant TEXT NOT NULL REFERENCES participants(participant),
    step INTEGER NOT NULL,
    phase TEXT NOT NULL,
    task TEXT,
    mode TEXT,
    run TEXT,
    trial_id INTEGER REFERENCES trials(trial_id),
    item TEXT NOT NULL,
    value INTEGER NOT NULL,
    answered_at TEXT NOT NULL,
    UNIQUE (session_id, step, item)
);
{ANSWERS_DDL};
CREATE TABLE events (
    event_id INTEGER PRIMARY KEY,
    session_id INTEGER REFERENCES sessions(session_id),
    participant TEXT,
    at TEXT NOT NULL,
    kind TEXT NOT NULL,
    detail TEXT NOT NULL DEFAULT '{{}}'
);
CREATE INDEX trials_by_session ON trials(session_id, step);
CREATE INDEX events_by_session ON events(session_id);
"""

TABLES = (
    "schema_version",
    "protocols",
    "participants",
    "demographics",
    "sessions",
    "assignments",
    "leases",
    "trials",
    "samples",
    "ratings",
    "answers",
    "events",
)

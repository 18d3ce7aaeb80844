"""The store's SQLite schema, version ``SCHEMA_VERSION``.

One row in ``schema_version`` says which schema and which protocol (study id + content hash)
wrote the file; ``protocols`` keeps that protocol's full TOML text keyed by its content hash, so
the exact study definition can be rebuilt from the store alone. Demographics live in their own table, apart from trial data. ``samples`` holds
one row per control tick, keyed by ``(trial_id, tick)``; the 7-vectors are spread over columns
``q1..q7`` etc. so the file stays readable with any SQLite client.
"""

from __future__ import annotations

SCHEMA_VERSION = 3
"""Version 2 added the ``protocols`` table, version 3 the samples' ``motion_agreement`` and
``rationality`` columns; an older file is read as it is (no stored protocol text, those sample
columns empty) and upgraded when opened read-write (``MIGRATIONS``)."""

READABLE_VERSIONS = (1, 2, 3)

PROTOCOLS_DDL = """
CREATE TABLE protocols (
    content_hash TEXT PRIMARY KEY,
    protocol_id TEXT NOT NULL,
    protocol_version TEXT NOT NULL,
    text TEXT NOT NULL,
    recorded_at TEXT NOT NULL
)"""

MIGRATIONS: dict[int, tuple[str, ...]] = {
    1: (PROTOCOLS_DDL,),
    2: (
        "ALTER TABLE samples ADD COLUMN motion_agreement REAL",
        "ALTER TABLE samples ADD COLUMN rationality REAL",
    ),
}
"""``{from_version: statements}`` that bring a file to ``from_version + 1``."""

DOF = 7
"""Joint-space vectors stored per sample (the Panda arm's 7 joints)."""

VECTOR_PREFIXES = ("q", "u", "p", "cmd")
SAMPLE_COLUMNS: tuple[str, ...] = (
    "trial_id",
    "tick",
    "t",
    *(f"{prefix}{i}" for prefix in VECTOR_PREFIXES for i in range(1, DOF + 1)),
    "alpha",
    "confidence",
    "predicted",
    "probabilities",
    "target_x",
    "target_y",
    "target_z",
    "ee_x",
    "ee_y",
    "ee_z",
    "gripper",
    "events",
    "motion_agreement",
    "rationality",
)
"""Column order of a sample row (``predicted`` is the goal index; ``probabilities`` and
``events`` are JSON lists; ``motion_agreement`` and ``rationality`` (version 3) come last, where
``ALTER TABLE`` puts them in an upgraded file)."""

_SAMPLE_DDL = ",\n    ".join(
    ["trial_id INTEGER NOT NULL REFERENCES trials(trial_id)", "tick INTEGER NOT NULL"]
    + [f"{c} REAL" for c in SAMPLE_COLUMNS[2:] if c not in ("predicted", "probabilities", "events")]
    + ["predicted INTEGER", "probabilities TEXT NOT NULL", "events TEXT NOT NULL DEFAULT '[]'"]
    + ["PRIMARY KEY (trial_id, tick)"]
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
    "events",
)

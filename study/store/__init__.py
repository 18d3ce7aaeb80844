"""The study store: one SQLite file (WAL, versioned schema) per study.

``Store.open(path, protocol_id=, protocol_hash=, protocol_text=)`` for sessions (use
``study.session.open_store(path, protocol)``), ``Store.open_readonly(path)`` for export and
analysis. Tables: protocols (the full text of the study's protocol), participants, demographics
(apart from trial data), sessions, assignments (the schedule), leases, trials, samples (one row
per control tick, columns from ``app.trial.samples``), ratings, answers (the other
questionnaire items), events. The record classes are
what ``Store``'s readers return.
"""

from study.store.errors import (
    DuplicateParticipantError,
    InvalidParticipantIdError,
    NotAStoreError,
    ProtocolMismatchError,
    ReadOnlyStoreError,
    SampleFormatError,
    SchemaVersionError,
    SessionLockedError,
    StoreDamagedError,
    StoreError,
    StoreFullError,
    StoreNotWritableError,
    StoreWriteError,
    UnknownParticipantError,
)
from study.store.opening import changed_sections
from study.store.orphans import ORPHAN_NOTE
from study.store.records import (
    AnswerRecord,
    AssignmentRecord,
    EventRecord,
    Lease,
    ParticipantRecord,
    RatingRecord,
    SessionRecord,
    StoreMeta,
    TrialRecord,
)
from study.store.schema import SAMPLE_COLUMNS, SCHEMA_VERSION, TABLES
from study.store.store import Store
from study.store.transaction import Transaction
from study.store.values import check_participant_id, now_iso

__all__ = [
    "ORPHAN_NOTE",
    "SAMPLE_COLUMNS",
    "SCHEMA_VERSION",
    "TABLES",
    "AnswerRecord",
    "AssignmentRecord",
    "DuplicateParticipantError",
    "EventRecord",
    "InvalidParticipantIdError",
    "Lease",
    "NotAStoreError",
    "ParticipantRecord",
    "ProtocolMismatchError",
    "RatingRecord",
    "ReadOnlyStoreError",
    "SampleFormatError",
    "SchemaVersionError",
    "SessionLockedError",
    "SessionRecord",
    "Store",
    "StoreDamagedError",
    "StoreError",
    "StoreFullError",
    "StoreMeta",
    "StoreNotWritableError",
    "StoreWriteError",
    "Transaction",
    "TrialRecord",
    "UnknownParticipantError",
    "changed_sections",
    "check_participant_id",
    "now_iso",
]

"""Tidy long-format tables from a study store, and the files an export writes.

``tidy_tables(store_or_path)`` (``study.export.tables``) is the one place that defines the tables;
``python -m study export`` writes them with ``write_export`` (``study.export.files``) as CSV and
Parquet beside a codebook (``study.codebook``), the protocol's text and ``metadata.json``
(``study.export.metadata``). Their columns are in ``study.export.columns``; which protocol a
store was run with is ``study.export.source``. The store is opened read-only and never written.
"""

from __future__ import annotations

from study.export.columns import (
    ANSWER_COLUMNS,
    DEFAULT_POINTS,
    EVENT_COLUMNS,
    PARTICIPANT_COLUMNS,
    RATING_COLUMNS,
    RECRUITMENT_COLUMNS,
    SAMPLE_KEY,
    SESSION_COLUMNS,
    TABLE_NAMES,
    TRIAL_COLUMNS,
    participant_item_column,
)
from study.export.errors import ExportError
from study.export.files import EXPORT_EXTRAS, EXPORT_FORMATS, stale_export_files, write_export
from study.export.metadata import excluded_participants, export_metadata, retention_pending
from study.export.source import find_protocol, resolve_protocol
from study.export.tables import tidy_tables

__all__ = [
    "ANSWER_COLUMNS",
    "DEFAULT_POINTS",
    "EVENT_COLUMNS",
    "EXPORT_EXTRAS",
    "EXPORT_FORMATS",
    "PARTICIPANT_COLUMNS",
    "RATING_COLUMNS",
    "RECRUITMENT_COLUMNS",
    "SAMPLE_KEY",
    "SESSION_COLUMNS",
    "TABLE_NAMES",
    "TRIAL_COLUMNS",
    "ExportError",
    "excluded_participants",
    "export_metadata",
    "find_protocol",
    "participant_item_column",
    "resolve_protocol",
    "retention_pending",
    "stale_export_files",
    "tidy_tables",
    "write_export",
]

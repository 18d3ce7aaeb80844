"""The export's error."""

from __future__ import annotations

from study.errors import StudyError


class ExportError(StudyError, ValueError):
    """The store cannot be exported (missing, not a store, inconsistent rows)."""

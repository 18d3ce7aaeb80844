"""Typed errors of the analysis package: each message says what was wrong and what to do."""

from __future__ import annotations


class AnalysisError(Exception):
    """Base class of every error the analysis package raises on purpose."""


class DataError(AnalysisError, ValueError):
    """The input data cannot be analysed as asked (missing columns, bad values, bad design)."""


class SchemaError(DataError):
    """A table lacks a column the analysis needs, or a column has the wrong kind of values."""


class DesignError(DataError):
    """The design is not analysable as specified: missing cells, one-level factors, too few subjects.

    ``missing`` maps each incomplete subject to the cells it lacks (empty when not applicable).
    """

    def __init__(self, message: str, *, missing: dict[str, list[str]] | None = None) -> None:
        super().__init__(message)
        self.missing: dict[str, list[str]] = dict(missing or {})


class SourceError(AnalysisError):
    """A study store, exported directory or protocol file cannot be read."""

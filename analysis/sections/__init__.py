"""The report's sections, in order: each module one section, with its text and (for the tests)
its rows of the statistics table.

A section module defines ``section(ctx: ReportContext) -> Section | None`` (``None``: nothing
to show) and, if it reports tests, ``rows(res: StudyResults) -> list[dict]`` of
:data:`analysis.statistics_rows.STAT_COLUMNS`. A new section is one module and one line in
``SECTIONS``: the data first (who, descriptives, ratings, data quality), then Fig. 7, success,
contacts and the decoy, and the tests where n allows. The paper's design gets the paper's
sections (timing, preferences, prediction); any other design (``res.factors``) the general ones
instead: the design table, ratings by condition, ANOVA and post-hoc comparisons by factor.
"""

from __future__ import annotations

from typing import Any

from analysis.render import Section
from analysis.sections import (
    appendix,
    condition_descriptives,
    condition_ratings,
    contact_counts,
    data,
    data_notes,
    data_quality,
    decoy,
    factor_anova,
    factor_design_table,
    factor_posthoc,
    factor_ratings,
    fig7_arbitration,
    no_tests,
    paper_vs_reviewer,
    prediction_tests,
    preference_tests,
    task_success,
    timing_tests,
)
from analysis.sections.context import ReportContext
from analysis.study_results import StudyResults

SECTIONS = (
    data,
    factor_design_table,
    condition_descriptives,
    condition_ratings,
    factor_ratings,
    data_quality,
    no_tests,
    fig7_arbitration,
    decoy,
    task_success,
    contact_counts,
    paper_vs_reviewer,
    timing_tests,
    factor_anova,
    factor_posthoc,
    preference_tests,
    prediction_tests,
    appendix,
    data_notes,
)
"""The report's sections in the order they appear."""


def report_sections(ctx: ReportContext) -> list[Section]:
    """Every section that has something to show, in order."""
    return [s for part in SECTIONS if (s := part.section(ctx)) is not None]


def statistics_rows(res: StudyResults) -> list[dict[str, Any]]:
    """Every section's rows of the statistics table, in the sections' order."""
    return [row for part in SECTIONS if hasattr(part, "rows") for row in part.rows(res)]


__all__ = ["SECTIONS", "ReportContext", "report_sections", "statistics_rows"]

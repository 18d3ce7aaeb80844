"""Section "Notes on the data": every note of the analysis (skipped parts, dropped rows)."""

from __future__ import annotations

from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    if not ctx.res.notes:
        return None
    return Section("Notes on the data", paragraphs=list(ctx.res.notes))

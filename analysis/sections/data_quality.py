"""Section "Data quality per participant" (:mod:`analysis.quality`)."""

from __future__ import annotations

from analysis.quality import quality_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section:
    return quality_section(ctx.tables)

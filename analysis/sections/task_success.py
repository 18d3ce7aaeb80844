"""Section "Task success by condition" (:mod:`analysis.outcomes`); tests only where n allows."""

from __future__ import annotations

from analysis.outcomes import success_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    return success_section(ctx.tables, modes=ctx.modes, tests=ctx.res.inferential)

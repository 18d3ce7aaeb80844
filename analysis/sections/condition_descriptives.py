"""Section "Descriptives by condition" (:mod:`analysis.descriptives`), with Fig. 8."""

from __future__ import annotations

from analysis.descriptives import descriptive_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section:
    sec = descriptive_section(ctx.tables, modes=ctx.modes)
    sec.figures += [ctx.figures[k] for k in ("fig8",) if k in ctx.figures]
    return sec

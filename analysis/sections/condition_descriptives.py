"""Section "Descriptives by condition" (:mod:`analysis.descriptives`), with Fig. 8."""

from __future__ import annotations

from analysis.descriptives import descriptive_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section:
    """By task and mode, and by every other declared factor where the design is not the
    paper's (an intent cue crossed with the modes, a between-subjects input mapping)."""
    design = ctx.res.factors.design if ctx.res.factors is not None else None
    split = [] if design is None else [f for f in design.factors if f not in ("task", "mode")]
    sec = descriptive_section(ctx.tables, modes=ctx.modes, split=split)
    sec.figures += [ctx.figures[k] for k in ("fig8",) if k in ctx.figures]
    return sec

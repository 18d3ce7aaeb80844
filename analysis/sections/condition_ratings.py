"""Section "Ratings by condition" (:mod:`analysis.ratings`), with Fig. 8's ratings: per task
and mode, for the paper's design (another design has :mod:`analysis.sections.factor_ratings`)."""

from __future__ import annotations

from analysis.ratings import ratings_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    if ctx.res.factors is not None:  # another design: by condition of its factors instead
        return None
    figures = [ctx.figures[k] for k in ("fig8_ratings",) if k in ctx.figures]
    return ratings_section(ctx.tables, modes=ctx.modes, figures=figures)

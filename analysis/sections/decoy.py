"""Section "Wrong prediction: how long the robot predicts the decoy" (:mod:`analysis.decoy_share`)."""

from __future__ import annotations

from analysis.decoy_share import decoy_section
from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    return decoy_section(ctx.tables)

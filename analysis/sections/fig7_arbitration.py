"""Section "Arbitration (Fig. 7)", when the protocol's arbitration tables were drawn."""

from __future__ import annotations

from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    if "fig7" not in ctx.figures:
        return None
    return Section(
        "Arbitration (Fig. 7)",
        paragraphs=[
            "α as a function of the confidence c for each mode, from the protocol's "
            "[modes.*].arbitration tables through app.blending.arbitration_from_config."
        ],
        figures=[ctx.figures["fig7"]],
    )

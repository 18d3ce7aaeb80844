"""Section "Statistical tests: not computed", when too few participants allow none."""

from __future__ import annotations

from analysis.render import Section
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    res = ctx.res
    if res.inferential:
        return None
    return Section(
        "Statistical tests: not computed",
        paragraphs=[res.why_no_tests[0].upper() + res.why_no_tests[1:] + "."],
    )

"""Section "Appendix: time per participant and cell (s)"."""

from __future__ import annotations

from analysis.render import Section, Table, fmt
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    if ctx.res.timing is None:
        return None
    wide = ctx.res.timing.cells.pivot_table(
        index="participant", columns=["task", "mode"], values="duration_s", observed=True
    )
    wide.columns = [f"{t} {m}" for t, m in wide.columns]
    return Section(
        "Appendix: time per participant and cell (s)",
        tables=[Table("Analysed durations", wide.map(fmt).reset_index())],
    )

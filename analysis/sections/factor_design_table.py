"""Section "Design": the declared factors, within or between subjects, their levels, the
conditions and the participants per between-subject group (a design other than the paper's)."""

from __future__ import annotations

import pandas as pd

from analysis.render import Section, Table
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    fa = ctx.res.factors
    if fa is None:
        return None
    d, cells = fa.design, fa.cells
    per_level = [
        ", ".join(f"{v}: {cells.loc[cells[f] == v, 'participant'].nunique()}" for v in d.factors[f])
        for f in d.factors
    ]
    frame = pd.DataFrame(
        {
            "factor": list(d.factors),
            "varied": [
                "between subjects" if f in d.between else "within subjects" for f in d.factors
            ],
            "levels": [", ".join(v) for v in d.factors.values()],
            "participants per level": per_level,
        }
    )
    sec = Section("Design")
    sec.paragraphs.append(
        f"The protocol's factors as the data have them: {len(d.conditions)} condition(s) within "
        "subjects (every combination of the within factors' levels)"
        + (f", participants split by {', '.join(d.between)}" if d.between else "")
        + ". Each measure below is analysed over these factors."
    )
    if d.dropped:
        sec.paragraphs.append(
            "Declared but with one level in the data (left out of the models): "
            + "; ".join(d.dropped)
            + "."
        )
    sec.tables.append(Table("Factors", frame))
    return sec

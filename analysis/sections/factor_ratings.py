"""Section "Ratings by condition" of a design other than the paper's: every Likert item the
protocol asks after a run, per condition (:mod:`analysis.item_ratings`)."""

from __future__ import annotations

import pandas as pd

from analysis.descriptives import MISSING, show
from analysis.render import Section, Table
from analysis.sections.context import ReportContext


def section(ctx: ReportContext) -> Section | None:
    fa = ctx.res.factors
    if fa is None or fa.ratings.empty:
        return None
    r = fa.ratings
    r = r.assign(
        cell=[f"{show(m, 2)} ({show(s, 2)})" for m, s in zip(r["mean"], r["sd"], strict=True)]
    )
    frame = r.pivot_table(
        index="condition", columns="item", values="cell", aggfunc="first", sort=False
    )[list(fa.items)]
    frame["n"] = r.groupby("condition", sort=False)["n"].max()
    sec = Section("Ratings by condition")
    sec.paragraphs.append(
        f"Every item the protocol asks after a run ({', '.join(fa.items)}), per condition: mean "
        f"(SD) over the runs (one answer per participant and run). {MISSING}: not defined. "
        "The tests of each item are in the ANOVA section."
    )
    sec.tables.append(Table("Ratings after each run: mean (SD)", frame.reset_index()))
    medians = r.pivot_table(index="condition", columns="item", values="median", sort=False)
    sec.tables.append(
        Table(
            "Ratings after each run: median",
            pd.DataFrame(medians[list(fa.items)].map(lambda v: show(v, 1))).reset_index(),
        )
    )
    return sec

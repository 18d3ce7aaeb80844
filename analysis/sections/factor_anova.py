"""Section "ANOVA by factor" of a design other than the paper's: per measure (the run's
duration, every after-run item) the condition means, the split-plot (RM) ANOVA over the
within and between factors and the random-intercept mixed model (:mod:`analysis.factor_analysis`).

``rows(res)``: their F tests as statistics rows, ``effect`` = ``"<measure>: <effect>"``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from analysis.factor_analysis import FactorAnalysis, MeasureAnalysis
from analysis.render import Section, Table, fmt
from analysis.sections.context import ReportContext
from analysis.sections.text import assumes, rm_table
from analysis.split_plot import SplitPlotResult
from analysis.statistics_rows import anova_rows
from analysis.study_results import StudyResults

ANOVA, MIXED = "factor_anova", "factor_mixed"


def rows(res: StudyResults) -> list[dict[str, Any]]:
    if res.factors is None:
        return []
    out: list[dict[str, Any]] = []
    for m, ma in res.factors.measures.items():
        if ma.anova is not None:
            table = ma.anova.table.assign(effect=m + ": " + ma.anova.table["effect"])
            out += anova_rows(
                ANOVA,
                table,
                "split-plot ANOVA" if ma.anova.between else "repeated-measures ANOVA",
                "univariate split-plot ANOVA on participant condition means, type III between "
                "terms; error df = df_E (n - groups); GG/HF corrections",
            )
        if ma.mixed is not None:
            table = ma.mixed.table.assign(effect=m + ": " + ma.mixed.table["effect"])
            out += anova_rows(MIXED, table, "linear mixed model (type III Wald F)")
    return out


def _stats_of(res: StudyResults, analysis: str, measure: str) -> pd.DataFrame:
    s = res.statistics
    s = s[(s["analysis"] == analysis) & s["effect"].str.startswith(f"{measure}: ")]
    return s.assign(effect=s["effect"].str.removeprefix(f"{measure}: "))


def condition_means(fit: SplitPlotResult) -> pd.DataFrame:
    """Per between group and within condition: the mean (SD) of participants' means, n."""
    cells, groups = fit.cells, fit.groups
    keys = (
        [tuple(map(str, r)) for r in groups[list(fit.between)].itertuples(index=False)]
        if fit.between
        else [()] * len(cells.subjects)
    )
    rows = []
    for key in dict.fromkeys(sorted(keys)):
        member = np.array([k == key for k in keys])
        for c, cond in enumerate(cells.cells):
            v = cells.values[member, c]
            labels = dict(zip([*fit.between, *cells.factors], [*key, *cond], strict=True))
            sd = float(v.std(ddof=1)) if len(v) > 1 else np.nan
            rows.append({**labels, "mean (SD)": f"{fmt(float(v.mean()))} ({fmt(sd)})", "n": len(v)})
    return pd.DataFrame(rows)


def _measure_tables(res: StudyResults, m: str, ma: MeasureAnalysis) -> list[Table]:
    tables = []
    if ma.anova is not None:
        tables.append(Table(f"{m}: condition means (participant means)", condition_means(ma.anova)))
        frame = rm_table(ma.anova.table, ANOVA, _stats_of(res, ANOVA, m))
        frame.insert(1, "error term", ma.anova.table["error"])
        tables.append(
            Table(
                f"{m}: {'split-plot' if ma.anova.between else 'repeated-measures'} ANOVA "
                f"({ma.anova.n_subjects} participants)",
                frame,
                assumes(ANOVA),
            )
        )
    if ma.mixed is not None:
        tables.append(
            Table(
                f"{m}: linear mixed model, random intercept per participant ({ma.mixed.n} runs)",
                rm_table(ma.mixed.table, MIXED, _stats_of(res, MIXED, m)),
                assumes(MIXED),
            )
        )
    return tables


def section(ctx: ReportContext) -> Section | None:
    fa: FactorAnalysis | None = ctx.res.factors
    if fa is None or not fa.measures:
        return None
    sec = Section("ANOVA by factor")
    sec.paragraphs.append(
        "Each measure on the declared factors: the ANOVA on each participant's mean per "
        "condition (within factors as repeated measures"
        + (f", {', '.join(fa.design.between)} between subjects" if fa.design.between else "")
        + "), and the mixed model on every run with a random intercept per participant "
        "(Satterthwaite df)."
    )
    for m, ma in fa.measures.items():
        sec.tables += _measure_tables(ctx.res, m, ma)
        sec.paragraphs += [f"{m}: {n}." for n in ma.notes if "skipped" in n]
    return sec

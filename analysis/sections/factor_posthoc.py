"""Section "Post-hoc comparisons by factor" of a design other than the paper's: every pair of
conditions and of each factor's levels, per measure, with Bonferroni and Holm corrections
(:mod:`analysis.pairwise`). ``rows(res)``: one statistics row per comparison."""

from __future__ import annotations

from typing import Any

import pandas as pd

from analysis.render import Section, Table, fmt, fmt_p
from analysis.sections.context import ReportContext
from analysis.sections.text import assumes, ci, df_text
from analysis.statistics_rows import stat_row
from analysis.study_results import StudyResults

ANALYSIS = "factor_posthoc"


def rows(res: StudyResults) -> list[dict[str, Any]]:
    if res.factors is None:
        return []
    out = []
    for m, ma in res.factors.measures.items():
        for r in ma.posthoc.itertuples():
            out.append(
                stat_row(
                    ANALYSIS,
                    f"{m}: {r.family}: {r.comparison}",
                    r.test,
                    r.df,
                    None,
                    r.t,
                    r.p,
                    es=r.effect_size,
                    es_name=r.effect_size_name,
                    p_bonf=r.p_bonf,
                    ci=(r.ci_low, r.ci_high),
                    method=f"{r.test}, Bonferroni and Holm over the family's {r.m}",
                    ci_level="95% CI of the mean difference (unadjusted)",
                    ci_low_bonf=r.ci_low_bonf,
                    ci_high_bonf=r.ci_high_bonf,
                    p_holm=r.p_holm,
                )
            )
    return out


def _table(posthoc: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "family": posthoc["family"],
            "comparison": posthoc["comparison"],
            "test": [
                f"{t}({df_text(d)})" for t, d in zip(posthoc["test"], posthoc["df"], strict=True)
            ],
            "t": posthoc["t"].map(fmt),
            "p": posthoc["p"].map(fmt_p),
            "p Bonferroni": posthoc["p_bonf"].map(fmt_p),
            "p Holm": posthoc["p_holm"].map(fmt_p),
            "difference [95% CI]": [
                f"{fmt(d)} {ci(lo, hi)}"
                for d, lo, hi in zip(
                    posthoc["mean_diff"], posthoc["ci_low"], posthoc["ci_high"], strict=True
                )
            ],
            "effect size": [
                f"{n} = {fmt(v)}"
                for n, v in zip(posthoc["effect_size_name"], posthoc["effect_size"], strict=True)
            ],
        }
    )


def section(ctx: ReportContext) -> Section | None:
    fa = ctx.res.factors
    if fa is None or not any(not ma.posthoc.empty for ma in fa.measures.values()):
        return None
    sec = Section("Post-hoc comparisons by factor")
    sec.paragraphs.append(
        "Every pair of conditions, and every pair of each factor's levels (participants' "
        "means over the other factors), per measure; p corrected within each family "
        "(Bonferroni and Holm's step-down; Holm is never larger). " + assumes(ANALYSIS)
    )
    for m, ma in fa.measures.items():
        if not ma.posthoc.empty:
            sec.tables.append(Table(f"{m}: pairwise comparisons", _table(ma.posthoc)))
    return sec

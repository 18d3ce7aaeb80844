"""Section "Preferences": the statistics rows of the preference correlations and their text.

``rows(res)``: each Pearson r (as in the paper) and each repeated-measures r (reviewer's form).
``section(ctx)``: both as the report's tables.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from analysis.render import Section, Table, fmt, fmt_p
from analysis.sections.context import ReportContext
from analysis.sections.text import assumes, ci, no_paper_values
from analysis.statistics_rows import stat_row
from analysis.study_results import StudyResults


def rows(res: StudyResults) -> list[dict[str, Any]]:
    """A row per correlation, the paper's form first (none without correlations)."""
    out = []
    for analysis, table, test in (
        ("preference", res.correlations, "Pearson r"),
        ("preference_rmcorr", res.rm_correlations, "repeated-measures r"),
    ):
        if table is None:
            continue
        for r in table.itertuples():
            name = r.versus if r.measure == "preference_aggressive" else r.measure
            out.append(
                stat_row(
                    analysis,
                    name,
                    test,
                    r.df,
                    None,
                    r.r,
                    r.p,
                    es=r.r,
                    es_name="r",
                    ci=(r.ci_low, r.ci_high),
                    method=f"{test} on {r.n} pairs"
                    + (f" from {r.n_subjects} participants" if hasattr(r, "n_subjects") else ""),
                    ci_level="95% CI by Fisher's z",
                )
            )
    return out


def section(ctx: ReportContext) -> Section | None:
    res = ctx.res
    if res.correlations is None:
        return None
    sec = Section("Preferences")
    c, s = res.correlations, res.statistics
    sec.paragraphs.append(
        "Preference for the aggressive run (-3..+3) per participant and task against the "
        "time advantage of aggressive (timid minus aggressive duration), and each rating's "
        "aggressive-minus-timid difference against the preference."
    )
    corr = pd.DataFrame(
        {
            "measure": c["measure"],
            "versus": c["versus"],
            "r": [f"r({fmt(d, 0)}) = {fmt(r)}" for d, r in zip(c["df"], c["r"], strict=True)],
            "p": c["p"].map(fmt_p),
            "95% CI": [ci(a, b) for a, b in zip(c["ci_low"], c["ci_high"], strict=True)],
        }
    )
    if res.paper_comparable["preference"]:
        corr["paper r"] = s[s.analysis == "preference"]["paper_value"].map(fmt).to_numpy()
    else:
        sec.paragraphs.append(no_paper_values(res))
    sec.tables.append(Table("Pearson correlations (as in the paper)", corr, assumes("preference")))
    if res.rm_correlations is not None:
        sec.tables.append(_rm_correlations_table(res.rm_correlations))
    return sec


def _rm_correlations_table(rc: pd.DataFrame) -> Table:
    return Table(
        "Repeated-measures correlations (reviewer's form)",
        pd.DataFrame(
            {
                "measure": rc["measure"],
                "versus": rc["versus"],
                "r_rm": [
                    f"r({fmt(d, 0)}) = {fmt(r)}" for d, r in zip(rc["df"], rc["r"], strict=True)
                ],
                "p": rc["p"].map(fmt_p),
                "95% CI": [ci(a, b) for a, b in zip(rc["ci_low"], rc["ci_high"], strict=True)],
                "pairs": rc["n"],
                "participants": rc["n_subjects"],
            }
        ),
        assumes("preference_rmcorr"),
    )

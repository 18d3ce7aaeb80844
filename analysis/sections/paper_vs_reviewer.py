"""Section "The paper's tests beside the reviewer's forms" (:func:`analysis.form_pairs.form_pairs`)."""

from __future__ import annotations

import pandas as pd

from analysis.form_pairs import form_pairs
from analysis.render import Section, Table
from analysis.sections.context import ReportContext
from analysis.sections.text import stat_text

STAT = {"timing_ancova": "F", "timing_posthoc": "t", "preference": "r", "prediction_anova": "F"}
FAMILY = {
    "timing_ancova": "timing model",
    "timing_posthoc": "post-hoc (Bonferroni p)",
    "preference": "preference correlation",
    "prediction_anova": "prediction model",
}

TEXT = (
    'Each of the paper\'s tests (kept below, labelled "as in the paper") treats repeated '
    "measurements of one participant as independent somewhere. Beside each is the analysis a "
    "reviewer would ask for: the timing model as a linear mixed model with a random intercept "
    "per participant (type III Wald F, Satterthwaite df); the post-hoc tests on one mean per "
    "participant; the preference correlations as repeated-measures correlations (Bakdash & "
    "Marusich 2017); the prediction model as a repeated-measures ANOVA over participant x "
    "condition x predictor. Where the paper's form gives the smaller p, counting "
    "repeated measurements as independent worked in its favour. The planned t(7) comparisons are already on one difference per "
    "participant and have no second form."
)


def section(ctx: ReportContext) -> Section | None:
    pairs = form_pairs(ctx.res.statistics)
    if pairs.empty:
        return None
    frame = pd.DataFrame(
        {
            "analysis": pairs["analysis"].map(FAMILY),
            "effect": pairs["effect"],
            "as in the paper": [
                stat_text(STAT[r.analysis], r.paper_df1, r.paper_df2, r.paper_statistic, r.paper_p)
                for r in pairs.itertuples()
            ],
            "reviewer's form": [
                stat_text(
                    STAT[r.analysis],
                    r.reviewer_df1,
                    r.reviewer_df2,
                    r.reviewer_statistic,
                    r.reviewer_p,
                )
                for r in pairs.itertuples()
            ],
            "paper's p smaller": pairs["paper_form_smaller_p"].map(
                lambda v: "yes" if v is True else ("" if v is None else "no")
            ),
        }
    )
    sec = Section("The paper's tests beside the reviewer's forms")
    sec.paragraphs.append(TEXT)
    sec.tables.append(
        Table(
            "Paper's form and reviewer's form, side by side",
            frame,
            "Post-hoc p are Bonferroni-adjusted within their family.",
        )
    )
    return sec

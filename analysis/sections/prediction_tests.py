"""Section "Prediction (section 5.2)": the statistics rows of the prediction models and their
text.

``rows(res)``: the factorial ANOVA on the success rate (as in the paper) and its R², and the
repeated-measures ANOVA over participant x condition x predictor (reviewer's form).
``section(ctx)``: the replay's success rates and times, those models, and Fig. 9.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from analysis.render import Section, Table, fmt
from analysis.sections.context import ReportContext
from analysis.sections.text import anova_table, assumes, no_paper_values, rm_table
from analysis.statistics_rows import anova_rows, stat_row
from analysis.study_results import StudyResults


def rows(res: StudyResults) -> list[dict[str, Any]]:
    """The prediction models' rows (none without them)."""
    out: list[dict[str, Any]] = []
    if res.prediction is not None:
        out += anova_rows(
            "prediction_anova",
            res.prediction.table,
            f"factorial ANOVA (OLS, type {res.prediction.ss_type} SS)",
            "OLS, residual df = N - cells",
        )
        out.append(
            stat_row(
                "prediction_anova",
                "R^2",
                "coefficient of determination",
                np.nan,
                None,
                res.prediction.r2,
                np.nan,
            )
        )
    if res.prediction_rm is not None:
        out += anova_rows(
            "prediction_rm",
            res.prediction_rm.table,
            "repeated-measures ANOVA (participant x condition x predictor)",
            "univariate RM ANOVA on participant means, error df = df_E (n - 1)",
        )
    return out


def section(ctx: ReportContext) -> Section | None:
    res = ctx.res
    if res.prediction_summary is None:
        return None
    sec = Section("Prediction (section 5.2)")
    p, s = res.prediction, res.statistics
    with_paper = res.paper_comparable["prediction"]
    sec.paragraphs += _text(ctx, res.prediction_summary, with_paper)
    sec.tables.append(_summary_table(res.prediction_summary))
    if p is not None:
        sec.tables.append(
            Table(
                "Factorial ANOVA on the success rate (as in the paper)",
                anova_table(p.table, "prediction_anova", s, with_paper),
                assumes("prediction_anova"),
            )
        )
    if res.prediction_rm is not None:
        sec.tables.append(
            Table(
                f"Repeated-measures ANOVA on the success rate, participant x condition x "
                f"predictor ({res.prediction_rm.n_subjects} participants; reviewer's form)",
                rm_table(res.prediction_rm.table, "prediction_rm", s),
                assumes("prediction_rm"),
            )
        )
    sec.figures += [f for k, f in ctx.figures.items() if k == "fig9"]
    return sec


def _text(ctx: ReportContext, summary: pd.DataFrame, with_paper: bool) -> list[str]:
    """What was replayed, with which parameters, the model's fit, and why no paper values."""
    res, p = ctx.res, ctx.res.prediction
    out = [
        "Every logged user-target trajectory replayed through app.blending's predictors "
        f"({', '.join(summary['predictor'].unique())}); success rate = share "
        "of ticks predicting the target; time to the first lasting correct prediction from "
        "the trial's start."
    ]
    if ctx.choices:
        out.append("Predictor parameters: " + "; ".join(c.describe() for c in ctx.choices) + ".")
    if p is not None:
        paper_fit = (
            " (the paper reports R² = 0.9 for N = 128, residual df = 112)" if with_paper else ""
        )
        out.append(
            f"Factorial ANOVA (type {p.ss_type} SS): N = {p.n}, residual df = "
            f"{p.df_resid}, R² = {p.r2:.2f}{paper_fit}."
        )
    if not with_paper:
        out.append(no_paper_values(res, "design" if not res.paper_design else "predictors"))
    return out


def _summary_table(ps: pd.DataFrame) -> Table:
    return Table(
        "Success rate and time to a lasting correct prediction",
        pd.DataFrame(
            {
                "predictor": ps["predictor"],
                "mode": ps["mode"],
                "success rate": ps["success_rate"].map(lambda v: fmt(v, 3)),
                "SE": ps["success_se"].map(lambda v: fmt(v, 3)),
                "time to lasting correct (s)": ps["time_to_correct_s"].map(fmt),
                "never lastingly correct": ps["never_lasting"],
                "trials": ps["n"],
            }
        ),
    )

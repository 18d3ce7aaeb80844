"""One row of the statistics table: its columns, the form and assumption of each analysis,
and the builders of a row and of an ANOVA table's rows (partial eta squared with its CI)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from analysis.effect_size import np2_ci
from analysis.published import published

STAT_COLUMNS = [
    "analysis",
    "effect",
    "test",
    "df1",
    "df2",
    "statistic",
    "p",
    "p_bonf",
    "effect_size",
    "effect_size_name",
    "ci_low",
    "ci_high",
    "paper_value",
    "paper_df",
    "paper_p",
    "form",
    "method",
    "assumes",
    "ci_level",
    "ci_low_bonf",
    "ci_high_bonf",
    "eps_gg",
    "p_gg",
    "eps_hf",
    "p_hf",
    "mauchly_W",
    "mauchly_p",
]

PAPER_FORM, REVIEWER_FORM = "as in the paper", "reviewer"
FORMS = {
    "timing_ancova": PAPER_FORM,
    "timing_effects": PAPER_FORM,
    "timing_mean": PAPER_FORM,
    "timing_posthoc": PAPER_FORM,
    "timing_planned": PAPER_FORM,
    "preference": PAPER_FORM,
    "prediction_anova": PAPER_FORM,
    "timing_mixed": REVIEWER_FORM,
    "timing_rm": REVIEWER_FORM,
    "timing_posthoc_subject": REVIEWER_FORM,
    "timing_pairwise": REVIEWER_FORM,
    "preference_rmcorr": REVIEWER_FORM,
    "prediction_rm": REVIEWER_FORM,
    "factor_anova": REVIEWER_FORM,  # a design other than the paper's: today's forms only
    "factor_mixed": REVIEWER_FORM,
    "factor_posthoc": REVIEWER_FORM,
}
"""Which rows are the paper's own tests and which the forms a reviewer would ask for."""

ASSUMES = {
    "timing_ancova": "OLS on every time: errors independent given the covariates, equal "
    "variances, normal; a participant's times count as separate people, so "
    "participant-level covariates get N - cells - k df (anti-conservative)",
    "timing_mixed": "participants differ by a random intercept (equal correlation of a "
    "participant's times), normal random effects and residuals; Satterthwaite "
    "df from the REML fit",
    "timing_rm": "one mean per participant and cell; normal contrast scores; sphericity for "
    "effects with more than 1 df (GG/HF-corrected p and Mauchly's test given); "
    "2-level effects need none",
    "timing_posthoc": "two pairs per participant (one per difficulty; 16 for 8 people) "
    "treated as independent: anti-conservative; normal differences; "
    "Bonferroni within the family",
    "timing_posthoc_subject": "one difference per participant (the two difficulties averaged); "
    "normal differences; Bonferroni within the family",
    "timing_planned": "one difference per participant (already the reviewer's form); normal "
    "differences; Bonferroni within the family",
    "timing_pairwise": "one difference per participant; normal differences; Bonferroni within "
    "each task",
    "timing_effects": "difference of unweighted marginal means (descriptive)",
    "timing_mean": "descriptive",
    "preference": "Pearson r on every participant x task pair: a participant's tasks counted as "
    "independent and between-participant differences mixed into the association "
    "(anti-conservative)",
    "preference_rmcorr": "a common within-participant slope, independent normal errors within "
    "participants (Bakdash & Marusich 2017); df = N - participants - 1",
    "prediction_anova": "OLS on every replay: a trajectory's two replays (one per predictor) and "
    "a participant's trials counted as independent (anti-conservative)",
    "prediction_rm": "one mean per participant, condition and predictor; normal contrast scores; "
    "sphericity for effects with more than 1 df",
    "factor_anova": "one mean per participant and condition; normal contrast scores; equal "
    "covariance of them across between-subject groups; sphericity for effects with more than "
    "1 df (GG/HF-corrected p and Mauchly's test given)",
    "factor_mixed": "participants differ by a random intercept (equal correlation of a "
    "participant's runs), normal random effects and residuals; Satterthwaite df from the REML "
    "fit",
    "factor_posthoc": "one mean per participant and condition; normal differences (paired t) or "
    "normal groups with unequal variances allowed (Welch t); Bonferroni and Holm within each "
    "family",
}
"""The one-line assumption statement of each analysis."""


def stat_row(
    analysis: str,
    effect: str,
    test: str,
    df1: float,
    df2: float | None,
    stat: float,
    p: float,
    *,
    es: float = np.nan,
    es_name: str = "",
    p_bonf: float = np.nan,
    ci: tuple[float, float] = (np.nan, np.nan),
    method: str = "",
    ci_level: str = "",
    **extra: float,
) -> dict[str, Any]:
    pub = published(analysis, effect) or {}
    return {
        "analysis": analysis,
        "effect": effect,
        "test": test,
        "df1": df1,
        "df2": np.nan if df2 is None else df2,
        "statistic": stat,
        "p": p,
        "p_bonf": p_bonf,
        "effect_size": es,
        "effect_size_name": es_name,
        "ci_low": ci[0],
        "ci_high": ci[1],
        "paper_value": pub.get("value"),
        "paper_df": pub.get("df"),
        "paper_p": pub.get("p"),
        "form": FORMS.get(analysis, ""),
        "method": method,
        "assumes": ASSUMES.get(analysis, ""),
        "ci_level": ci_level,
        **extra,
    }


NP2_CI = "95% CI of partial eta squared (noncentral F)"


def anova_rows(
    analysis: str, table: pd.DataFrame, test: str, method: str = ""
) -> list[dict[str, Any]]:
    rows = []
    for r in table.itertuples():
        extra = {
            k: getattr(r, k)
            for k in ("eps_gg", "p_gg", "eps_hf", "p_hf", "mauchly_W", "mauchly_p")
            if hasattr(r, k)
        }
        rows.append(
            stat_row(
                analysis,
                r.effect,
                test,
                r.df1,
                r.df2,
                r.F,
                r.p,
                es=r.np2,
                es_name="partial eta squared",
                ci=np2_ci(r.F, r.df1, r.df2),
                method=getattr(r, "method", method),
                ci_level=NP2_CI
                + ("; sphericity-assumed df" if "eps_gg" in extra and r.df1 > 1 else ""),
                **extra,
            )
        )
    return rows

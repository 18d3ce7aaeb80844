"""Each paper-form test beside its reviewer-form counterpart (:func:`form_pairs`)."""

from __future__ import annotations

import numpy as np
import pandas as pd

PAIRS = {
    "timing_ancova": "timing_mixed",
    "timing_posthoc": "timing_posthoc_subject",
    "preference": "preference_rmcorr",
    "prediction_anova": "prediction_rm",
}
"""Each paper-form analysis and the reviewer-form analysis set beside it."""


FORM_PAIR_COLUMNS = [
    "analysis",
    "effect",
    "paper_test",
    "paper_df1",
    "paper_df2",
    "paper_statistic",
    "paper_p",
    "reviewer_analysis",
    "reviewer_test",
    "reviewer_df1",
    "reviewer_df2",
    "reviewer_statistic",
    "reviewer_p",
    "paper_form_smaller_p",
]


def form_pairs(statistics: pd.DataFrame) -> pd.DataFrame:
    """Each paper-form test beside its reviewer-form counterpart (same effect); p are the
    Bonferroni-adjusted ones where the test has them. ``paper_form_smaller_p``: the paper's form
    gives the smaller p (the direction in which its independence assumption errs); p equal to
    rounding (a mixed model on its boundary is the paper's OLS) is not smaller."""
    rows = []
    for paper, reviewer in PAIRS.items():
        a = statistics[statistics["analysis"] == paper]
        b = statistics[statistics["analysis"] == reviewer].set_index("effect")
        for r in a.itertuples():
            if r.effect not in b.index:
                continue
            q = b.loc[r.effect]
            pa = r.p_bonf if pd.notna(r.p_bonf) else r.p
            pb = q["p_bonf"] if pd.notna(q["p_bonf"]) else q["p"]
            rows.append(
                {
                    "analysis": paper,
                    "effect": r.effect,
                    "paper_test": r.test,
                    "paper_df1": r.df1,
                    "paper_df2": r.df2,
                    "paper_statistic": r.statistic,
                    "paper_p": pa,
                    "reviewer_analysis": reviewer,
                    "reviewer_test": q["test"],
                    "reviewer_df1": q["df1"],
                    "reviewer_df2": q["df2"],
                    "reviewer_statistic": q["statistic"],
                    "reviewer_p": pb,
                    "paper_form_smaller_p": bool(pa < pb and not np.isclose(pa, pb, rtol=1e-9))
                    if pd.notna(pa) and pd.notna(pb)
                    else None,
                }
            )
    return pd.DataFrame(rows, columns=FORM_PAIR_COLUMNS)

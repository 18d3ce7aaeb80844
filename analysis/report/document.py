"""results.json: metadata, model fits, every statistic, the form pairs and the notes."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from analysis.form_pairs import form_pairs
from analysis.study_results import StudyResults


def jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [jsonable(x) for x in v]
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if v is pd.NA or v is pd.NaT:
        return None
    return v


def results_document(
    res: StudyResults,
    meta: Mapping[str, Any],
    *,
    success: tuple[pd.DataFrame, pd.DataFrame] | None = None,
) -> dict[str, Any]:
    """Everything results.json holds: metadata, model fits, every statistic, notes, and (if
    given) the task success summary and paired comparisons of :mod:`analysis.outcomes`."""
    fits: dict[str, Any] = {}
    if res.timing is not None:
        a = res.timing.ancova
        fits["timing_ancova"] = {
            "r2": a.r2,
            "r2_adj": a.r2_adj,
            "n": a.n,
            "df_resid": a.df_resid,
            "ss_type": a.ss_type,
            "covariates": list(res.timing.covariates),
        }
        fits["timing_rm"] = {"n_subjects": res.timing.rm.n_subjects}
        if res.timing.mixed is not None:
            m = res.timing.mixed
            fits["timing_mixed"] = {
                "n": m.n,
                "n_subjects": m.n_subjects,
                "var_subject": m.var_subject,
                "var_resid": m.var_resid,
                "icc": m.icc,
                "df_method": m.df_method,
                "estimates": m.estimates.to_dict(orient="records"),
            }
    if res.prediction is not None:
        p = res.prediction
        fits["prediction_anova"] = {
            "r2": p.r2,
            "r2_adj": p.r2_adj,
            "n": p.n,
            "df_resid": p.df_resid,
            "ss_type": p.ss_type,
        }
    if res.prediction_rm is not None:
        fits["prediction_rm"] = {"n_subjects": res.prediction_rm.n_subjects}
    doc = {
        **meta,
        "fits": fits,
        "statistics": res.statistics.to_dict(orient="records"),
        "paper_vs_reviewer": form_pairs(res.statistics).to_dict(orient="records"),
        "notes": list(res.notes),
    }
    if res.prediction_summary is not None:
        doc["prediction_summary"] = res.prediction_summary.to_dict(orient="records")
    if res.timing is not None:
        doc["timing_summary"] = res.timing.summary.to_dict(orient="records")
    if success is not None and not success[0].empty:
        doc["success_summary"] = success[0].to_dict(orient="records")
        if not success[1].empty:
            doc["success_comparisons"] = success[1].to_dict(orient="records")
    return jsonable(doc)

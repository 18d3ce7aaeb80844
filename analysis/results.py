"""All of the paper's analyses on one study, and every statistic as one tidy table.

``analyse(tables)`` runs timing (section 5.1), preferences and prediction (5.2); a section
whose data are missing is skipped with a note saying why, so one gap never hides the rest.
``statistics`` has one row per test: analysis, effect, test, df1, df2, statistic, p, p_bonf,
effect_size (+ its name), ci_low, ci_high, and the paper's value where it reports one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from analysis.anova import FactorialAnovaResult
from analysis.correlations import preference_correlations
from analysis.errors import AnalysisError
from analysis.load import StudyTables, task_cells
from analysis.prediction_eval import PREDICTORS, evaluate_predictions, prediction_anova
from analysis.published import published
from analysis.timing import (
    FACTORS,
    LEVELS,
    TimingAnalysis,
    design_levels,
    summarise,
    timing_analysis,
)

STAT_COLUMNS = ["analysis", "effect", "test", "df1", "df2", "statistic", "p", "p_bonf",
                "effect_size", "effect_size_name", "ci_low", "ci_high", "paper_value",
                "paper_df", "paper_p"]


@dataclass
class StudyResults:
    cells: pd.DataFrame
    timing: TimingAnalysis | None = None
    correlations: pd.DataFrame | None = None
    preferences: pd.DataFrame | None = None
    evals: pd.DataFrame | None = None
    prediction: FactorialAnovaResult | None = None
    prediction_summary: pd.DataFrame | None = None
    statistics: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=STAT_COLUMNS))
    notes: list[str] = field(default_factory=list)
    paper_design: bool = True      # difficulty x correctness x mode, the paper's two levels each
    paper_predictors: bool = True  # amnesic and memory-based with eq. 9's squared velocity

    @property
    def paper_comparable(self) -> dict[str, bool]:
        """Per analysis family: are the paper's values comparable with ours?"""
        return {"timing": self.paper_design, "preference": self.paper_design,
                "prediction": self.paper_design and self.paper_predictors}


def is_paper_design(cells: pd.DataFrame,
                    levels: Mapping[str, Sequence[str]] | None = None) -> bool:
    """The data's design is the paper's: difficulty, correctness and mode, two levels each."""
    return design_levels(cells, levels) == {f: LEVELS[f] for f in FACTORS}


def is_paper_predictors(predictors: Mapping[str, Mapping[str, Any]]) -> bool:
    """The replayed predictors are the paper's two: amnesic and eq. 9 with squared velocity."""
    kinds = {n: dict(c).get("kind") for n, c in predictors.items()}
    return (kinds == {"amnesic": "amnesic", "memory": "memory"}
            and dict(predictors["memory"]).get("cost") == "squared_velocity")


def _row(analysis: str, effect: str, test: str, df1: float, df2: float | None, stat: float,
         p: float, *, es: float = np.nan, es_name: str = "", p_bonf: float = np.nan,
         ci: tuple[float, float] = (np.nan, np.nan)) -> dict[str, Any]:
    pub = published(analysis, effect) or {}
    return {"analysis": analysis, "effect": effect, "test": test, "df1": df1,
            "df2": np.nan if df2 is None else df2, "statistic": stat, "p": p, "p_bonf": p_bonf,
            "effect_size": es, "effect_size_name": es_name, "ci_low": ci[0], "ci_high": ci[1],
            "paper_value": pub.get("value"), "paper_df": pub.get("df"), "paper_p": pub.get("p")}


def _anova_rows(analysis: str, table: pd.DataFrame, test: str) -> list[dict[str, Any]]:
    return [_row(analysis, r.effect, test, r.df1, r.df2, r.F, r.p, es=r.np2,
                 es_name="partial eta squared") for r in table.itertuples()]


def _paper_df1(df: object) -> float | None:
    try:
        return float(str(df).split(",")[0])
    except ValueError:
        return None


def statistics_table(res: StudyResults) -> pd.DataFrame:
    """Every statistic of ``res`` as rows of ``STAT_COLUMNS``.

    The paper's value is given only where the design (and, for prediction, the predictors)
    match the paper's and an F test has the paper's numerator df; elsewhere it is empty.
    """
    rows: list[dict[str, Any]] = []
    if res.timing is not None:
        t = res.timing
        rows += _anova_rows("timing_ancova", t.ancova.table,
                            f"factorial ANOVA with covariates (OLS, type {t.ancova.ss_type} SS)")
        rows.append(_row("timing_ancova", "R^2", "coefficient of determination", np.nan, None,
                         t.ancova.r2, np.nan))
        rows += _anova_rows("timing_rm", t.rm.table, "repeated-measures ANOVA")
        for r in t.main_effects.itertuples():
            rows.append(_row("timing_effects", r.effect, f"mean difference {r.contrast} (s)",
                             np.nan, None, r.mean_diff, np.nan))
        rows.append(_row("timing_mean", "duration_s", "mean time per task (s)", np.nan, None,
                         float(t.cells["duration_s"].mean()), np.nan))
        for r in t.comparisons.itertuples():
            rows.append(_row(r.analysis, r.comparison, "paired t (Bonferroni)", r.df, None, r.t,
                             r.p, es=r.d_z, es_name="Cohen's d_z", p_bonf=r.p_bonf,
                             ci=(r.ci_low, r.ci_high)))
    if res.correlations is not None:
        for r in res.correlations.itertuples():
            name = r.versus if r.measure == "preference_aggressive" else r.measure
            rows.append(_row("preference", name, "Pearson r", r.df, None, r.r, r.p, es=r.r,
                             es_name="r", ci=(r.ci_low, r.ci_high)))
    if res.prediction is not None:
        rows += _anova_rows("prediction_anova", res.prediction.table,
                            f"factorial ANOVA (OLS, type {res.prediction.ss_type} SS)")
        rows.append(_row("prediction_anova", "R^2", "coefficient of determination", np.nan,
                         None, res.prediction.r2, np.nan))
    comparable = res.paper_comparable
    for r in rows:
        family = ("prediction" if r["analysis"].startswith("prediction")
                  else "preference" if r["analysis"] == "preference" else "timing")
        df1 = _paper_df1(r["paper_df"]) if r["paper_value"] is not None else None
        f_mismatch = df1 is not None and "ANOVA" in r["test"] and r["df1"] != df1
        if not comparable[family] or f_mismatch:
            r.update(paper_value=None, paper_df=None, paper_p=None)
    return pd.DataFrame(rows, columns=STAT_COLUMNS)


def analyse(tables: StudyTables, *,
            predictors: Mapping[str, Mapping[str, Any]] = PREDICTORS,
            successful_only: bool = False,
            levels: Mapping[str, Sequence[str]] | None = None) -> StudyResults:
    """Run every analysis of section 5 that the data allow; see the module docstring.

    ``levels``: the protocol's factor levels, to order them as the protocol does.
    """
    cells, notes = task_cells(tables.trials, successful_only=successful_only)
    res = StudyResults(cells=cells, notes=[*tables.notes, *notes],
                       paper_predictors=is_paper_predictors(predictors))
    if cells.empty:
        res.notes.append("no completed task trials: nothing to analyse")
        return res
    res.paper_design = is_paper_design(cells, levels)
    try:
        res.timing = timing_analysis(cells, levels=levels)
        res.notes += [f"timing: {n}" for n in res.timing.notes]
    except AnalysisError as e:
        res.notes.append(f"timing analysis skipped: {e}")
    try:
        res.correlations, res.preferences = preference_correlations(cells)
    except AnalysisError as e:
        res.notes.append(f"preference analysis skipped: {e}")
    if tables.samples is None or tables.samples.empty:
        res.notes.append("prediction analysis skipped: the study has no samples")
    else:
        try:
            res.evals, pnotes = evaluate_predictions(cells, tables.samples, predictors=predictors)
            res.notes += [f"prediction: {n}" for n in pnotes]
            summ = res.evals.groupby(["predictor", "mode"], sort=False)
            res.prediction_summary = summ.agg(
                success_rate=("success_rate", "mean"),
                success_se=("success_rate", lambda s: s.std() / np.sqrt(len(s))),
                time_to_correct_s=("time_to_correct_s", "mean"),
                never_lasting=("time_to_correct_s", lambda s: int(s.isna().sum())),
                n=("success_rate", "size")).reset_index()
            res.prediction = prediction_anova(res.evals, levels=levels)
        except AnalysisError as e:
            res.notes.append(f"prediction analysis skipped: {e}")
    res.statistics = statistics_table(res)
    return res


__all__ = ["STAT_COLUMNS", "StudyResults", "analyse", "statistics_table", "summarise"]

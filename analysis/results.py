"""All of the paper's analyses on one study, and every statistic as one tidy table.

``analyse(tables)`` runs timing (section 5.1), preferences and prediction (5.2); a section
whose data are missing is skipped with a note saying why, so one gap never hides the rest.
No test runs on fewer than ``MIN_PARTICIPANTS`` participants with completed task runs
(``StudyResults.inferential`` is then False and a note says why): with one participant the
paper's forms would treat one person's runs as independent people, and with two every
participant-level test has a single error df. The descriptive parts (the prediction replay's
success rates) are still computed.
``statistics`` has one row per test: analysis, effect, test, df1, df2, statistic, p, p_bonf,
effect_size (+ its name), ci_low, ci_high, and the paper's value where it reports one; then
``form`` ("as in the paper", or "reviewer" for the analyses a reviewer would ask for beside
them), ``method`` (estimation and df), ``assumes`` (one line), ``ci_level`` (what the CI is),
the Bonferroni CI of Bonferroni-adjusted tests, and for repeated-measures F tests the GG/HF
epsilons and corrected p and Mauchly's test. ``form_pairs`` sets each paper-form test beside
its reviewer-form counterpart.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from analysis.anova import FactorialAnovaResult
from analysis.correlations import preference_correlations
from analysis.effect_size import np2_ci
from analysis.errors import AnalysisError
from analysis.load import StudyTables, task_cells
from analysis.prediction_eval import (
    PREDICTORS,
    evaluate_predictions,
    prediction_anova,
    prediction_rm_anova,
)
from analysis.published import published
from analysis.rm_anova import RMAnovaResult
from analysis.rmcorr import rm_corr_table
from analysis.timing import (
    FACTORS,
    LEVELS,
    TimingAnalysis,
    design_levels,
    summarise,
    timing_analysis,
)

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
}
"""The one-line assumption statement of each analysis."""

PAIRS = {
    "timing_ancova": "timing_mixed",
    "timing_posthoc": "timing_posthoc_subject",
    "preference": "preference_rmcorr",
    "prediction_anova": "prediction_rm",
}
"""Each paper-form analysis and the reviewer-form analysis set beside it."""


@dataclass
class StudyResults:
    cells: pd.DataFrame
    timing: TimingAnalysis | None = None
    correlations: pd.DataFrame | None = None
    rm_correlations: pd.DataFrame | None = None  # repeated-measures r beside each Pearson r
    preferences: pd.DataFrame | None = None
    evals: pd.DataFrame | None = None
    prediction: FactorialAnovaResult | None = None
    prediction_rm: RMAnovaResult | None = None  # participant x condition x predictor
    prediction_summary: pd.DataFrame | None = None
    statistics: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=STAT_COLUMNS))
    notes: list[str] = field(default_factory=list)
    paper_design: bool = True  # difficulty x correctness x mode, the paper's two levels each
    paper_predictors: bool = True  # amnesic and memory-based with eq. 9's squared velocity
    inferential: bool = True  # enough participants for tests (MIN_PARTICIPANTS)
    why_no_tests: str = ""

    @property
    def paper_comparable(self) -> dict[str, bool]:
        """Per analysis family: are the paper's values comparable with ours?"""
        return {
            "timing": self.paper_design,
            "preference": self.paper_design,
            "prediction": self.paper_design and self.paper_predictors,
        }


def is_paper_design(cells: pd.DataFrame, levels: Mapping[str, Sequence[str]] | None = None) -> bool:
    """The data's design is the paper's: difficulty, correctness and mode, two levels each."""
    return design_levels(cells, levels) == {f: LEVELS[f] for f in FACTORS}


def is_paper_predictors(predictors: Mapping[str, Mapping[str, Any]]) -> bool:
    """The replayed predictors are the paper's two: amnesic and eq. 9 with squared velocity."""
    kinds = {n: dict(c).get("kind") for n, c in predictors.items()}
    return (
        kinds == {"amnesic": "amnesic", "memory": "memory"}
        and dict(predictors["memory"]).get("cost") == "squared_velocity"
    )


def _row(
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


def _anova_rows(
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
            _row(
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
        rows += _anova_rows(
            "timing_ancova",
            t.ancova.table,
            f"factorial ANOVA with covariates (OLS, type {t.ancova.ss_type} SS)",
            "OLS, residual df = N - parameters",
        )
        rows.append(
            _row(
                "timing_ancova",
                "R^2",
                "coefficient of determination",
                np.nan,
                None,
                t.ancova.r2,
                np.nan,
            )
        )
        if t.mixed is not None:
            rows += _anova_rows(
                "timing_mixed",
                t.mixed.table,
                "linear mixed model with covariates (type III Wald F)",
            )
        rows += _anova_rows(
            "timing_rm",
            t.rm.table,
            "repeated-measures ANOVA",
            "univariate RM ANOVA, error df = df_E (n - 1); GG/HF corrections",
        )
        for r in t.main_effects.itertuples():
            rows.append(
                _row(
                    "timing_effects",
                    r.effect,
                    f"mean difference {r.contrast} (s)",
                    np.nan,
                    None,
                    r.mean_diff,
                    np.nan,
                )
            )
        rows.append(
            _row(
                "timing_mean",
                "duration_s",
                "mean time per task (s)",
                np.nan,
                None,
                float(t.cells["duration_s"].mean()),
                np.nan,
            )
        )
        for r in t.comparisons.itertuples():
            rows.append(
                _row(
                    r.analysis,
                    r.comparison,
                    "paired t (Bonferroni)",
                    r.df,
                    None,
                    r.t,
                    r.p,
                    es=r.d_z,
                    es_name="Cohen's d_z",
                    p_bonf=r.p_bonf,
                    ci=(r.ci_low, r.ci_high),
                    method=f"paired t on {r.n} pairs, Bonferroni over {r.m}",
                    ci_level="95% CI of the mean difference, unadjusted; "
                    f"ci_*_bonf: Bonferroni-adjusted (m = {r.m})",
                    ci_low_bonf=r.ci_low_bonf,
                    ci_high_bonf=r.ci_high_bonf,
                )
            )
    for analysis, table, test in (
        ("preference", res.correlations, "Pearson r"),
        ("preference_rmcorr", res.rm_correlations, "repeated-measures r"),
    ):
        if table is None:
            continue
        for r in table.itertuples():
            name = r.versus if r.measure == "preference_aggressive" else r.measure
            rows.append(
                _row(
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
    if res.prediction is not None:
        rows += _anova_rows(
            "prediction_anova",
            res.prediction.table,
            f"factorial ANOVA (OLS, type {res.prediction.ss_type} SS)",
            "OLS, residual df = N - cells",
        )
        rows.append(
            _row(
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
        rows += _anova_rows(
            "prediction_rm",
            res.prediction_rm.table,
            "repeated-measures ANOVA (participant x condition x predictor)",
            "univariate RM ANOVA on participant means, error df = df_E (n - 1)",
        )
    comparable = res.paper_comparable
    for r in rows:
        family = (
            "prediction"
            if r["analysis"].startswith("prediction")
            else "preference"
            if r["analysis"] == "preference"
            else "timing"
        )
        df1 = _paper_df1(r["paper_df"]) if r["paper_value"] is not None else None
        f_mismatch = df1 is not None and "ANOVA" in r["test"] and r["df1"] != df1
        if not comparable[family] or f_mismatch:
            r.update(paper_value=None, paper_df=None, paper_p=None)
    return pd.DataFrame(rows, columns=STAT_COLUMNS)


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


MIN_PARTICIPANTS = 3
"""Fewest participants with completed task runs on which any test is computed."""


def too_few_participants(n: int) -> str:
    """Why no test is computed for ``n`` participants (``""`` when there are enough)."""
    if n >= MIN_PARTICIPANTS:
        return ""
    return (
        f"no tests, p-values or confidence intervals: {n} participant(s) with completed task "
        f"runs, and the report computes none below {MIN_PARTICIPANTS} (with one participant a "
        "test would count one person's runs as independent people; with two, every "
        "participant-level test has a single error df); the descriptives above stand"
    )


def analyse(
    tables: StudyTables,
    *,
    predictors: Mapping[str, Mapping[str, Any]] = PREDICTORS,
    successful_only: bool = False,
    levels: Mapping[str, Sequence[str]] | None = None,
) -> StudyResults:
    """Run every analysis of section 5 that the data allow; see the module docstring.

    ``levels``: the protocol's factor levels, to order them as the protocol does.
    """
    cells, notes = task_cells(tables.trials, successful_only=successful_only)
    res = StudyResults(
        cells=cells, notes=[*tables.notes, *notes], paper_predictors=is_paper_predictors(predictors)
    )
    if cells.empty:
        res.inferential, res.why_no_tests = False, "no completed task runs: nothing to test"
        res.notes.append("no completed task trials: nothing to analyse")
        return res
    res.paper_design = is_paper_design(cells, levels)
    res.why_no_tests = too_few_participants(int(cells["participant"].nunique()))
    res.inferential = not res.why_no_tests
    if not res.inferential:
        res.notes.append(res.why_no_tests)
        _prediction(res, tables, cells, predictors, levels, tests=False)
        res.statistics = statistics_table(res)
        return res
    try:
        res.timing = timing_analysis(cells, levels=levels)
        res.notes += [f"timing: {n}" for n in res.timing.notes]
    except AnalysisError as e:
        res.notes.append(f"timing analysis skipped: {e}")
    try:
        res.correlations, res.preferences = preference_correlations(cells)
    except AnalysisError as e:
        res.notes.append(f"preference analysis skipped: {e}")
    if res.correlations is not None and res.preferences is not None:
        try:
            res.rm_correlations = rm_corr_table(
                res.preferences,
                list(zip(res.correlations["measure"], res.correlations["versus"], strict=True)),
                subject="participant",
            )
        except AnalysisError as e:
            res.notes.append(f"repeated-measures correlations skipped: {e}")
    _prediction(res, tables, cells, predictors, levels, tests=True)
    res.statistics = statistics_table(res)
    return res


def _prediction(
    res: StudyResults,
    tables: StudyTables,
    cells: pd.DataFrame,
    predictors: Mapping[str, Mapping[str, Any]],
    levels: Mapping[str, Sequence[str]] | None,
    *,
    tests: bool,
) -> None:
    """The prediction replay and its summary; with ``tests`` also its ANOVAs."""
    if tables.samples is None or tables.samples.empty:
        res.notes.append("prediction analysis skipped: the study has no samples")
        return
    try:
        res.evals, pnotes = evaluate_predictions(cells, tables.samples, predictors=predictors)
        res.notes += [f"prediction: {n}" for n in pnotes]
        summ = res.evals.groupby(["predictor", "mode"], sort=False)
        res.prediction_summary = summ.agg(
            success_rate=("success_rate", "mean"),
            success_se=("success_rate", lambda s: s.std() / np.sqrt(len(s))),
            time_to_correct_s=("time_to_correct_s", "mean"),
            never_lasting=("time_to_correct_s", lambda s: int(s.isna().sum())),
            n=("success_rate", "size"),
        ).reset_index()
        if tests:
            res.prediction = prediction_anova(res.evals, levels=levels)
    except AnalysisError as e:
        res.notes.append(f"prediction analysis skipped: {e}")
    if tests and res.evals is not None and res.prediction is not None:
        try:
            res.prediction_rm = prediction_rm_anova(res.evals, levels=levels)
            res.notes += [f"prediction (repeated measures): {n}" for n in res.prediction_rm.notes]
        except AnalysisError as e:
            res.notes.append(f"prediction repeated-measures model skipped: {e}")


__all__ = [
    "ASSUMES",
    "FORMS",
    "MIN_PARTICIPANTS",
    "STAT_COLUMNS",
    "StudyResults",
    "analyse",
    "form_pairs",
    "statistics_table",
    "summarise",
]

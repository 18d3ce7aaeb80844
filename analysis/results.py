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
from typing import Any

import numpy as np
import pandas as pd

from analysis.correlations import preference_correlations
from analysis.errors import AnalysisError
from analysis.factor_analysis import factor_analysis
from analysis.factor_design import condition_cells, factor_design, is_paper_factors
from analysis.form_pairs import PAIRS, form_pairs
from analysis.item_ratings import rated_items
from analysis.load import PAPER_FACTORS, StudyTables, task_cells
from analysis.prediction_eval import (
    PREDICTORS,
    evaluate_predictions,
    prediction_anova,
    prediction_rm_anova,
)
from analysis.rmcorr import rm_corr_table
from analysis.sections import statistics_rows
from analysis.statistics_rows import ASSUMES, FORMS, STAT_COLUMNS
from analysis.study_results import StudyResults, is_paper_design, is_paper_predictors
from analysis.timing import summarise, timing_analysis


def _paper_df1(df: object) -> float | None:
    """The numerator df of a published df text ("1, 53" -> 1.0); ``None`` if it has none."""
    try:
        return float(str(df).split(",")[0])
    except ValueError:
        return None


def statistics_table(res: StudyResults) -> pd.DataFrame:
    """Every statistic of ``res`` as rows of ``STAT_COLUMNS``.

    The paper's value is given only where the design (and, for prediction, the predictors)
    match the paper's and an F test has the paper's numerator df; elsewhere it is empty.
    """
    rows = statistics_rows(res)
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
    holm = ["p_holm"] if any("p_holm" in r for r in rows) else []  # post-hoc by factor only
    return pd.DataFrame(rows, columns=[*STAT_COLUMNS, *holm])


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
    between: Sequence[str] = (),
    items: Sequence[str] = (),
) -> StudyResults:
    """Run every analysis of section 5 that the data allow; see the module docstring.

    ``levels``: the protocol's factor levels, to order them as the protocol does (default: the
    paper's factors the trials have). ``between``: the factors varied between subjects;
    ``items``: the Likert items rated after each run. A design other than the paper's
    difficulty x correctness x mode (all within) is analysed by factor name instead
    (:mod:`analysis.factor_analysis`: ``StudyResults.factors``).
    """
    declared = list(levels or [f for f in PAPER_FACTORS if f in tables.trials.columns])
    if not is_paper_factors(declared, between):
        return _analyse_by_factor(
            tables,
            dict(levels) if levels else declared,
            between=between,
            items=items,
            successful_only=successful_only,
            paper_predictors=is_paper_predictors(predictors),
        )
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


def _analyse_by_factor(
    tables: StudyTables,
    factors: Mapping[str, Sequence[str]] | Sequence[str],
    *,
    between: Sequence[str],
    items: Sequence[str],
    successful_only: bool,
    paper_predictors: bool,
) -> StudyResults:
    """A design of other factors: the split-plot ANOVA, mixed model and post-hoc tests of each
    measure and the ratings by condition (tests from ``MIN_PARTICIPANTS`` on)."""
    design = factor_design(tables.trials, factors, between=between)
    cells, notes = condition_cells(tables.trials, design, successful_only=successful_only)
    res = StudyResults(
        cells=cells,
        notes=[*tables.notes, *notes],
        paper_design=False,
        paper_predictors=paper_predictors,
    )
    if cells.empty:
        res.inferential, res.why_no_tests = False, "no completed task runs: nothing to test"
        res.notes.append("no completed task trials: nothing to analyse")
        return res
    res.why_no_tests = too_few_participants(int(cells["participant"].nunique()))
    res.inferential = not res.why_no_tests
    if not res.inferential:
        res.notes.append(res.why_no_tests)
    res.factors = factor_analysis(
        cells, design, items=rated_items(cells, tables.ratings, items), tests=res.inferential
    )
    res.notes += list(res.factors.notes)
    res.notes.append(
        "the design is not the paper's difficulty x correctness x mode: analysed by factor "
        f"name ({_design_text(design.factors, design.between)}); the paper's timing, "
        "preference and prediction analyses are not run"
    )
    res.statistics = statistics_table(res)
    return res


def _design_text(factors: Mapping[str, Sequence[str]], between: Sequence[str]) -> str:
    return "; ".join(
        f"{f} ({'between' if f in between else 'within'}: {', '.join(v)})"
        for f, v in factors.items()
    )


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
    "PAIRS",
    "STAT_COLUMNS",
    "StudyResults",
    "analyse",
    "form_pairs",
    "statistics_table",
    "summarise",
]

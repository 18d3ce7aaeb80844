"""Analysis of shared-control studies: tidy data, the paper's statistics, figures and reports.

Public API (imported lazily, so ``python -m analysis anova`` starts fast)::

    load_tables(db=|export_dir=) -> StudyTables      from_frames(trials, samples, ...)
    task_cells(trials) -> (one row per participant x task x mode, notes)
    rm_anova(data, dv=, subject=, within=) -> RMAnovaResult (.table: effect, df1, df2, F, p,
        np2, SS, SS_error, eps_gg, p_gg, eps_hf, p_hf, mauchly_W, mauchly_chi2, mauchly_df,
        mauchly_p)
    mixed_anova(data, dv=, subject=, factors=, covariates=) -> MixedModelResult  random
        intercept per subject, type III Wald F on Satterthwaite df (.table, .estimates)
    rm_corr(data, x=, y=, subject=)   repeated-measures correlation (Bakdash & Marusich 2017)
    np2_ci(F, df1, df2)               CI of partial eta squared (noncentral F)
    factorial_anova(data, dv=, factors=, covariates=, ss_type=3) -> FactorialAnovaResult
    covariate_anova(data, dv=, subject=, within=, covariates=)   the paper's F(1, 53) model
    paired_t(a, b), paired_comparisons([...]), pearson(x, y), preference_correlations(cells)
    timing_analysis(cells) -> TimingAnalysis       section 5.1
    evaluate_predictions(cells, samples), prediction_anova(evals), replay(points, traj, pred)
    analyse(tables) -> StudyResults (.statistics: every test as one tidy table, paper's and
        reviewer's forms), form_pairs(statistics) -> the two forms side by side
    pilot_cells(cells), bootstrap_power(pilot, ns=, b=) -> PowerResult   power of H1/H2
    write_report(tables, out_dir, protocol_path=) -> ReportFiles
    synthetic_tables(n_participants, seed=, rate_hz=)   simulated data for tests/benchmarks
Errors: AnalysisError > DataError (SchemaError, DesignError), SourceError.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "AnalysisError": "analysis.errors",
    "DataError": "analysis.errors",
    "DesignError": "analysis.errors",
    "SchemaError": "analysis.errors",
    "SourceError": "analysis.errors",
    "StudyTables": "analysis.load",
    "from_frames": "analysis.load",
    "from_export": "analysis.load",
    "from_store": "analysis.load",
    "load_tables": "analysis.load",
    "task_cells": "analysis.load",
    "cell_means": "analysis.design",
    "RMAnovaResult": "analysis.rm_anova",
    "rm_anova": "analysis.rm_anova",
    "FactorialAnovaResult": "analysis.anova",
    "factorial_anova": "analysis.anova",
    "covariate_anova": "analysis.anova",
    "paired_t": "analysis.posthoc",
    "paired_comparisons": "analysis.posthoc",
    "Comparison": "analysis.posthoc",
    "pearson": "analysis.correlations",
    "preference_correlations": "analysis.correlations",
    "TimingAnalysis": "analysis.timing",
    "timing_analysis": "analysis.timing",
    "PREDICTORS": "analysis.prediction_eval",
    "replay": "analysis.prediction_eval",
    "evaluate_predictions": "analysis.prediction_eval",
    "prediction_anova": "analysis.prediction_eval",
    "first_lasting_correct": "analysis.prediction_eval",
    "StudyResults": "analysis.results",
    "analyse": "analysis.results",
    "write_report": "analysis.report",
    "ReportFiles": "analysis.report",
    "load_protocol_info": "analysis.protocol_info",
    "synthetic_tables": "analysis.synthetic",
    "MixedModelResult": "analysis.mixed",
    "mixed_anova": "analysis.mixed",
    "rm_corr": "analysis.rmcorr",
    "np2_ci": "analysis.effect_size",
    "form_pairs": "analysis.results",
    "prediction_rm_anova": "analysis.prediction_eval",
    "PilotCells": "analysis.power",
    "PowerResult": "analysis.power",
    "pilot_cells": "analysis.power",
    "bootstrap_power": "analysis.power",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'analysis' has no attribute {name!r}")

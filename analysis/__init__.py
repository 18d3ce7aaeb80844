"""Analysis of shared-control studies: tidy data, the paper's statistics, figures and reports.

The package exports the loader and the errors; everything else is imported from its module
(importing them all here would cost every ``python -m analysis`` command about 2-3 s of
matplotlib and statsmodels, measured with ``-X importtime``; the loader costs pandas only)::

    from analysis import load_tables, task_cells     tidy tables from a store or an export
    from analysis.results import analyse             every test of the paper, both forms
    from analysis.report import write_report         report.html, report.md, results.json
    from analysis.sections import SECTIONS           the report's sections, in order
    from analysis.rm_anova import rm_anova           repeated-measures ANOVA (GG/HF, Mauchly)
    from analysis.mixed import mixed_anova           random-intercept mixed model, type III F
    from analysis.split_plot import split_plot_anova within x between factors (split-plot)
    from analysis.factor_analysis import factor_analysis   any design by factor name
    from analysis.pairwise import pairwise_comparisons     every pair, Bonferroni and Holm
    from analysis.contrast_power import contrast_power     power of any declared contrast
    from analysis.anova import factorial_anova, covariate_anova
    from analysis.posthoc import paired_t, paired_comparisons
    from analysis.correlations import pearson, preference_correlations
    from analysis.rmcorr import rm_corr              repeated-measures correlation
    from analysis.effect_size import np2_ci          CI of partial eta squared
    from analysis.timing import timing_analysis      section 5.1
    from analysis.prediction_eval import evaluate_predictions, prediction_anova, replay
    from analysis.power import pilot_cells, bootstrap_power
    from analysis.synthetic import synthetic_tables  simulated data for tests and benchmarks

Errors: AnalysisError > DataError (SchemaError, DesignError), SourceError.
"""

from analysis.errors import AnalysisError, DataError, DesignError, SchemaError, SourceError
from analysis.load import StudyTables, from_frames, load_tables, task_cells

__all__ = [
    "AnalysisError",
    "DataError",
    "DesignError",
    "SchemaError",
    "SourceError",
    "StudyTables",
    "from_frames",
    "load_tables",
    "task_cells",
]

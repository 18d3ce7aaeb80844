"""Section "Timing (section 5.1)": the statistics rows of the timing analysis and their text.

``rows(res)``: the factorial ANOVA with covariates (as in the paper) and its R², the mixed
model and the repeated-measures ANOVA (reviewer's forms), the main effects as mean differences,
the mean time per task, and the paired comparisons. ``section(ctx)``: those as the report's
tables, and the time per task and mode.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from analysis.render import Section, Table, fmt, fmt_p
from analysis.sections.context import ReportContext
from analysis.sections.text import anova_table, assumes, ci, df_text, no_paper_values, rm_table
from analysis.statistics_rows import ASSUMES, anova_rows, stat_row
from analysis.study_results import StudyResults
from analysis.timing import TimingAnalysis

COMPARISONS = ["timing_posthoc", "timing_planned", "timing_pairwise", "timing_posthoc_subject"]
FORM = {
    "timing_posthoc": "as in the paper",
    "timing_planned": "as in the paper",
    "timing_posthoc_subject": "reviewer",
    "timing_pairwise": "reviewer",
}
"""Which paired comparisons are the paper's and which the reviewer's."""


def rows(res: StudyResults) -> list[dict[str, Any]]:
    """The timing analysis' statistics rows (none without a timing analysis)."""
    if res.timing is None:
        return []
    t = res.timing
    return [*_model_rows(t), *_descriptive_rows(t), *_comparison_rows(t)]


def _model_rows(t: TimingAnalysis) -> list[dict[str, Any]]:
    out = anova_rows(
        "timing_ancova",
        t.ancova.table,
        f"factorial ANOVA with covariates (OLS, type {t.ancova.ss_type} SS)",
        "OLS, residual df = N - parameters",
    )
    out.append(
        stat_row(
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
        out += anova_rows(
            "timing_mixed",
            t.mixed.table,
            "linear mixed model with covariates (type III Wald F)",
        )
    out += anova_rows(
        "timing_rm",
        t.rm.table,
        "repeated-measures ANOVA",
        "univariate RM ANOVA, error df = df_E (n - 1); GG/HF corrections",
    )
    return out


def _descriptive_rows(t: TimingAnalysis) -> list[dict[str, Any]]:
    out = [
        stat_row(
            "timing_effects",
            r.effect,
            f"mean difference {r.contrast} (s)",
            np.nan,
            None,
            r.mean_diff,
            np.nan,
        )
        for r in t.main_effects.itertuples()
    ]
    out.append(
        stat_row(
            "timing_mean",
            "duration_s",
            "mean time per task (s)",
            np.nan,
            None,
            float(t.cells["duration_s"].mean()),
            np.nan,
        )
    )
    return out


def _comparison_rows(t: TimingAnalysis) -> list[dict[str, Any]]:
    return [
        stat_row(
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
        for r in t.comparisons.itertuples()
    ]


def section(ctx: ReportContext) -> Section | None:
    res = ctx.res
    if res.timing is None:
        return None
    t, s = res.timing, res.statistics
    with_paper = res.paper_comparable["timing"]
    sec = Section("Timing (section 5.1)")
    sec.paragraphs.append(_model_text(t, with_paper))
    if not with_paper:
        sec.paragraphs.append(no_paper_values(res))
    sec.tables.append(
        Table(
            "Factorial ANOVA with covariates (as in the paper)",
            anova_table(t.ancova.table, "timing_ancova", s, with_paper),
            assumes("timing_ancova"),
        )
    )
    sec.tables += _mixed_tables(t, s)
    sec.tables.append(_effects_table(s, with_paper))
    sec.tables.append(
        Table(
            f"Repeated-measures ANOVA ({t.rm.n_subjects} participants)",
            rm_table(t.rm.table, "timing_rm", s),
            "Subjects as error strata: each effect's error df is its df "
            "times (n - 1); the paper reports only the covariate model "
            f"above. {assumes('timing_rm')}",
        )
    )
    if len(t.comparisons):
        sec.tables.append(_comparisons_table(t.comparisons, s, with_paper))
    sec.tables.append(_summary_table(t.summary, successful_only=ctx.successful_only))
    return sec


def _model_text(t: TimingAnalysis, with_paper: bool) -> str:
    paper_fit = " (the paper reports R² = 0.66 for N = 64, residual df = 53)" if with_paper else ""
    return (
        f"Factorial ANOVA with covariates: duration ~ {' × '.join(t.factors)}, "
        f"sum-to-zero contrasts, type {t.ancova.ss_type} sums of squares, covariates "
        f"{', '.join(t.covariates) or 'none'}; N = {t.ancova.n}, residual df = "
        f"{t.ancova.df_resid}, R² = {t.ancova.r2:.2f}{paper_fit}. "
        "Type III tests each effect at the unweighted cell means adjusted for all other "
        "terms and the covariates (SPSS GLM's default, the form the paper reports). Like "
        f"the paper's, this model treats the {t.ancova.n} times as independent given the "
        "covariates; the repeated-measures ANOVA below models the participant instead."
    )


def _mixed_tables(t: TimingAnalysis, s: pd.DataFrame) -> list[Table]:
    """The mixed model's F tests and its estimates (none without a mixed model)."""
    m = t.mixed
    if m is None:
        return []
    tests = Table(
        "Linear mixed model with a random intercept per participant (reviewer's form)",
        rm_table(m.table, "timing_mixed", s).assign(
            df=[
                f"{df_text(a)}, {df_text(b)}"
                for a, b in zip(m.table["df1"], m.table["df2"], strict=True)
            ]
        ),
        f"Same fixed effects and covariates; REML (residual variance profiled, as lme4): participant "
        f"variance {fmt(m.var_subject, 3)}, residual variance {fmt(m.var_resid, 3)} "
        f"(ICC {fmt(m.icc, 2)}); type III Wald F on {m.df_method} df; partial η² from "
        f"F and df. {assumes('timing_mixed')}",
    )
    est = m.estimates
    estimates = Table(
        "Mixed-model estimates (Satterthwaite t, 95% CI)",
        pd.DataFrame(
            {
                "term": est["term"],
                "contrast": est["contrast"],
                "estimate": est["estimate"].map(lambda v: fmt(v, 3)),
                "SE": est["se"].map(lambda v: fmt(v, 3)),
                "t": [
                    f"t({df_text(d)}) = {fmt(v)}" for d, v in zip(est["df"], est["t"], strict=True)
                ],
                "p": est["p"].map(fmt_p),
                "95% CI": [ci(a, b, 3) for a, b in zip(est["ci_low"], est["ci_high"], strict=True)],
            }
        ),
        "Factor contrasts are differences of unweighted marginal "
        "means (seconds); covariates are slopes per unit.",
    )
    return [tests, estimates]


def _effects_table(s: pd.DataFrame, with_paper: bool) -> Table:
    me = s[s.analysis == "timing_effects"]
    effects = pd.DataFrame(
        {
            "factor": me["effect"],
            "contrast": me["test"].str.replace("mean difference ", "").str.replace(" (s)", ""),
            "ours": me["statistic"].map(fmt),
        }
    )
    if with_paper:
        effects["paper"] = me["paper_value"].map(fmt)
    return Table("Main effects as mean differences (s)", effects)


def _comparisons_table(c: pd.DataFrame, s: pd.DataFrame, with_paper: bool) -> Table:
    comp = s[s.analysis.isin(COMPARISONS)].reset_index(drop=True)
    paired = pd.DataFrame(
        {
            "family": c["family"],
            "comparison": c["comparison"],
            "t": [f"t({fmt(d, 0)}) = {fmt(v)}" for d, v in zip(c["df"], c["t"], strict=True)],
            "p": c["p"].map(fmt_p),
            "p (Bonferroni)": c["p_bonf"].map(fmt_p),
            "mean diff (s)": c["mean_diff"].map(fmt),
            "95% CI (unadjusted)": [
                ci(a, b) for a, b in zip(c["ci_low"], c["ci_high"], strict=True)
            ],
            "Bonferroni CI": [
                ci(a, b) for a, b in zip(c["ci_low_bonf"], c["ci_high_bonf"], strict=True)
            ],
            "d_z": c["d_z"].map(fmt),
            "form": c["analysis"].map(FORM),
        }
    )
    if with_paper:
        paired["paper |t|"] = comp["paper_value"].map(fmt)
    return Table(
        "Paired comparisons (Bonferroni within each family)",
        paired,
        "Differences are first minus second"
        + ("; the paper reports |t|" if with_paper else "")
        + ". The Bonferroni CI uses t at 1 - .025/m, matching "
        "p (Bonferroni); the 95% CI is unadjusted. Assumes - "
        + "; ".join(
            f"{fam}: {ASSUMES[a]}"
            for fam, a in dict(zip(c["family"], c["analysis"], strict=True)).items()
        )
        + ".",
    )


def _summary_table(summ: pd.DataFrame, *, successful_only: bool) -> Table:
    return Table(
        "Time per task and mode (s), "
        + (
            "successful runs only"
            if successful_only
            else "all completed runs (failed runs until they ended)"
        ),
        pd.DataFrame(
            {
                "task": summ["task"],
                "mode": summ["mode"],
                "mean": summ["mean"].map(fmt),
                "SE": summ["se"].map(fmt),
                "n": summ["n"],
            }
        ),
    )

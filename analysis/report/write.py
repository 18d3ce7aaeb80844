"""The study report: HTML (self-contained, figures as inline SVG), Markdown, results.json.

``write_report(tables, out_dir)`` runs :func:`analysis.results.analyse`, draws the figures, and
writes ``report.html``, ``report.md``, ``results.json`` and ``figures/*.png|svg`` into
``out_dir``. Where the design (and for prediction, the predictors) are the paper's, tables put
the paper's published value beside ours; otherwise the report says why none are shown. The
header names the data source, the software version and the protocol's content hash; the
prediction section names the predictor parameters replayed (the protocol's, else the paper's).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import platform
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis import figures as figs
from analysis.contact_summary import contact_section
from analysis.decoy_share import decoy_section
from analysis.descriptives import descriptive_section
from analysis.errors import AnalysisError
from analysis.load import StudyTables
from analysis.outcomes import success_comparisons, success_section, success_summary
from analysis.prediction_eval import (
    PREDICTORS,
    PredictorChoice,
    goal_moves,
    make_predictor,
    protocol_predictors,
    replay,
    trial_goals,
    trial_trajectories,
)
from analysis.protocol_info import DEFAULT_PROTOCOL, ProtocolInfo, load_protocol_info
from analysis.quality import quality_section
from analysis.ratings import preference_summary, rating_summary, ratings_section
from analysis.render import (
    TITLE,
    Section,
    Table,
    fmt,
    fmt_p,
    render_html,
    render_markdown,
)
from analysis.results import ASSUMES, StudyResults, analyse, form_pairs
from analysis.timing import FACTORS, LEVELS

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class ReportFiles:
    html: Path
    markdown: Path
    results_json: Path
    figures: tuple[Path, ...]
    results: StudyResults


def software_info() -> dict[str, str]:
    """Package version, git commit and the versions of the numerical stack."""
    import matplotlib
    import scipy
    import statsmodels

    try:
        version = metadata.version("shared-control-platform")
    except metadata.PackageNotFoundError:
        version = "unknown"
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "analysis"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        commit = (commit + ("+local changes" if dirty else "")) or "unknown"
    except (OSError, subprocess.SubprocessError):
        commit = "unknown"
    return {
        "package": "shared-control-platform",
        "version": version,
        "commit": commit,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "pandas": pd.__version__,
        "scipy": scipy.__version__,
        "statsmodels": statsmodels.__version__,
        "matplotlib": matplotlib.__version__,
    }


def _anova_table(
    table: pd.DataFrame, analysis: str, stats: pd.DataFrame, with_paper: bool = True
) -> pd.DataFrame:
    """An ANOVA table; with the paper's F and p beside ours when ``with_paper``."""
    pub = stats[stats.analysis == analysis].set_index("effect")
    rows = []
    for r in table.itertuples():
        paper = pub.loc[r.effect] if r.effect in pub.index else None
        row = {
            "effect": r.effect,
            "df": f"{fmt(r.df1, 0)}, {fmt(r.df2, 0)}",
            "F": fmt(r.F),
            "p": fmt_p(r.p),
            "partial η²": fmt(r.np2, 3),
        }
        if with_paper:
            row["paper F"] = fmt(paper["paper_value"]) if paper is not None else ""
            row["paper p"] = fmt(paper["paper_p"]) if paper is not None else ""
        rows.append(row)
    return pd.DataFrame(rows)


def _assumes(analysis: str) -> str:
    return f"Assumes: {ASSUMES[analysis]}."


def _ci(lo: float, hi: float, digits: int = 2) -> str:
    """``[lo, hi]``, or "–" when either end is not defined (never an empty ``[, ]``)."""
    if pd.isna(lo) or pd.isna(hi):
        return "–"
    return f"[{fmt(lo, digits)}, {fmt(hi, digits)}]"


def _with_ci(value: float, lo: float, hi: float, digits: int = 2) -> str:
    if pd.isna(value):
        return ""
    ci = f" {_ci(lo, hi, digits)}" if pd.notna(lo) and pd.notna(hi) else ""
    return f"{fmt(value, digits)}{ci}"


def _df(v: float) -> str:
    """Integer df as integers (within rounding: a boundary fit's n - p), Satterthwaite df to
    one decimal."""
    return fmt(float(round(v)), 0) if abs(v - round(v)) < 1e-9 * max(1.0, abs(v)) else fmt(v, 1)


def _stat_text(stat: str, df1: float, df2: float, value: float, p: float) -> str:
    df = _df(df1) if pd.isna(df2) else f"{_df(df1)}, {_df(df2)}"
    return f"{stat}({df}) = {fmt(value)}, p {'' if fmt_p(p).startswith('<') else '= '}{fmt_p(p)}"


def _rm_table(table: pd.DataFrame, analysis: str, stats: pd.DataFrame) -> pd.DataFrame:
    """F-test rows with partial eta squared [95% CI]; for an RM ANOVA with an effect of more
    than 1 df also GG/HF epsilon and p and Mauchly's test."""
    st = stats[stats.analysis == analysis].set_index("effect")
    out = pd.DataFrame(
        {
            "effect": table["effect"],
            "df": [
                f"{fmt(a, 0)}, {fmt(b, 0)}" for a, b in zip(table["df1"], table["df2"], strict=True)
            ],
            "F": table["F"].map(fmt),
            "p": table["p"].map(fmt_p),
            "partial η² [95% CI]": [
                _with_ci(r.np2, st.loc[r.effect, "ci_low"], st.loc[r.effect, "ci_high"], 3)
                for r in table.itertuples()
            ],
        }
    )
    if "eps_gg" in table.columns and (table["df1"] > 1).any():
        multi = table["df1"] > 1
        out["ε GG"] = np.where(multi, table["eps_gg"].map(lambda v: fmt(v, 3)), "")
        out["p GG"] = np.where(multi, table["p_gg"].map(fmt_p), "")
        out["ε HF"] = np.where(multi, table["eps_hf"].map(lambda v: fmt(v, 3)), "")
        out["p HF"] = np.where(multi, table["p_hf"].map(fmt_p), "")
        out["Mauchly W"] = table["mauchly_W"].map(lambda v: fmt(v, 3))
        out["Mauchly p"] = table["mauchly_p"].map(fmt_p)
    return out


def _form_pairs_section(res: StudyResults) -> Section | None:
    pairs = form_pairs(res.statistics)
    if pairs.empty:
        return None
    stat = {"timing_ancova": "F", "timing_posthoc": "t", "preference": "r", "prediction_anova": "F"}
    family = {
        "timing_ancova": "timing model",
        "timing_posthoc": "post-hoc (Bonferroni p)",
        "preference": "preference correlation",
        "prediction_anova": "prediction model",
    }
    frame = pd.DataFrame(
        {
            "analysis": pairs["analysis"].map(family),
            "effect": pairs["effect"],
            "as in the paper": [
                _stat_text(stat[r.analysis], r.paper_df1, r.paper_df2, r.paper_statistic, r.paper_p)
                for r in pairs.itertuples()
            ],
            "reviewer's form": [
                _stat_text(
                    stat[r.analysis],
                    r.reviewer_df1,
                    r.reviewer_df2,
                    r.reviewer_statistic,
                    r.reviewer_p,
                )
                for r in pairs.itertuples()
            ],
            "paper's p smaller": pairs["paper_form_smaller_p"].map(
                lambda v: "yes" if v is True else ("" if v is None else "no")
            ),
        }
    )
    sec = Section("The paper's tests beside the reviewer's forms")
    sec.paragraphs.append(
        'Each of the paper\'s tests (kept below, labelled "as in the paper") treats repeated '
        "measurements of one participant as independent somewhere. Beside each is the analysis a "
        "reviewer would ask for: the timing model as a linear mixed model with a random intercept "
        "per participant (type III Wald F, Satterthwaite df); the post-hoc tests on one mean per "
        "participant; the preference correlations as repeated-measures correlations (Bakdash & "
        "Marusich 2017); the prediction model as a repeated-measures ANOVA over participant x "
        "condition x predictor. Where the paper's form gives the smaller p, counting "
        "repeated measurements as independent worked in its favour. The planned t(7) comparisons are already on one difference per "
        "participant and have no second form."
    )
    sec.tables.append(
        Table(
            "Paper's form and reviewer's form, side by side",
            frame,
            "Post-hoc p are Bonferroni-adjusted within their family.",
        )
    )
    return sec


def _per_participant(cells: pd.DataFrame) -> str:
    n = cells.groupby("participant").size()
    lo, hi = int(n.min()), int(n.max())
    return f"{lo} per participant" if lo == hi else f"{lo} to {hi} per participant"


def _design_text(levels: Mapping[str, tuple[str, ...]]) -> str:
    return "; ".join(f"{f}: {', '.join(v)}" for f, v in levels.items())


PAPER_DESIGN = "the paper's 2 x 2 x 2 (" + _design_text({f: LEVELS[f] for f in FACTORS}) + ")"


def _no_paper_values(res: StudyResults, what: str = "design") -> str:
    if what == "predictors":
        return (
            "The predictors replayed differ from the paper's (amnesic, and memory-based "
            "with the squared-velocity cost of eq. 9), so the paper's values are not shown."
        )
    levels = res.timing.levels if res.timing is not None else None
    ours = f" ({_design_text(levels)})" if levels else ""
    return f"This design{ours} differs from {PAPER_DESIGN}, so the paper's values are not shown."


def _data_section(res: StudyResults, tables: StudyTables, *, successful_only: bool) -> Section:
    """Who and what the report covers: participants included and left out (and why), runs,
    and which runs the analysed durations include."""
    data = Section("Data")
    trials, cells = tables.trials, res.cells
    excluded = tables.excluded
    enrolled = len(tables.participants) if not tables.participants.empty else None
    with_runs = trials["participant"].nunique() if not trials.empty else 0
    who = f"{with_runs} participant(s) with data"
    if enrolled is not None:
        who = f"{enrolled} participant(s) enrolled, {enrolled - len(excluded)} included"
    if excluded:
        who += "; left out: " + "; ".join(f"{p} ({why})" for p, why in excluded.items())
    p = tables.participants
    if not p.empty and "status" in p.columns:
        under_way = p.loc[p["status"].isin(["enrolled", "running"]), "participant"]
        if len(under_way):
            who += (
                f"; session still under way: {', '.join(map(str, under_way))} (their data as they"
                " stand; a retention question, if the protocol asks one, comes at the end)"
            )
    data.paragraphs.append(who + ".")
    if not cells.empty:
        n_part = cells["participant"].nunique()
        paper = " (paper: about 28 s)" if res.paper_design else ""
        which = (
            "successful task runs only (--successful-only)"
            if successful_only
            else "all completed task runs, a failed run counting the time until it ended"
        )
        ok = cells[cells["success"].astype(bool)] if "success" in cells.columns else cells
        data.paragraphs.append(
            f"{n_part} participant(s), {len(cells)} analysed task runs "
            f"({_per_participant(cells)}). Mean time per task over the analysed runs, {which}: "
            f"{cells['duration_s'].mean():.1f} s{paper}; over the successful runs alone: "
            + (f"{ok['duration_s'].mean():.1f} s ({len(ok)} runs)." if len(ok) else "none.")
        )
    if not trials.empty:
        cols = [c for c in ("phase", "status", "outcome") if c in trials.columns]
        counts = trials.groupby(cols, dropna=False).size().reset_index(name="trials")
        data.tables.append(Table("Trial attempts by phase, status and outcome", counts))
    return data


def _sections(
    res: StudyResults,
    figures: Mapping[str, figs.SavedFigure],
    tables: StudyTables,
    choices: Sequence[PredictorChoice] = (),
    *,
    modes: Sequence[str] | None = None,
    successful_only: bool = False,
    extra: Sequence[Section] = (),
) -> list[Section]:
    """Every section, in order: the data first (who, descriptives, ratings, data quality),
    then Fig. 7, ``extra`` (success, contacts, the decoy), and the tests where n allows."""
    s = res.statistics
    out: list[Section] = []
    data = _data_section(res, tables, successful_only=successful_only)
    out.append(data)
    descriptives = descriptive_section(tables, modes=modes)
    descriptives.figures += [figures[k] for k in ("fig8",) if k in figures]
    out.append(descriptives)
    ratings = ratings_section(
        tables, modes=modes, figures=[figures[k] for k in ("fig8_ratings",) if k in figures]
    )
    if ratings is not None:
        out.append(ratings)
    out.append(quality_section(tables))
    if not res.inferential:
        out.append(
            Section(
                "Statistical tests: not computed",
                paragraphs=[res.why_no_tests[0].upper() + res.why_no_tests[1:] + "."],
            )
        )
    if "fig7" in figures:
        out.append(
            Section(
                "Arbitration (Fig. 7)",
                paragraphs=[
                    "α as a function of the confidence c for each mode, from the protocol's "
                    "[modes.*].arbitration tables through app.blending.arbitration_from_config."
                ],
                figures=[figures["fig7"]],
            )
        )
    out += extra
    pairs = _form_pairs_section(res)
    if pairs is not None:
        out.append(pairs)
    if res.timing is not None:
        t = res.timing
        with_paper = res.paper_comparable["timing"]
        sec = Section("Timing (section 5.1)")
        paper_fit = (
            " (the paper reports R² = 0.66 for N = 64, residual df = 53)" if with_paper else ""
        )
        sec.paragraphs.append(
            f"Factorial ANOVA with covariates: duration ~ {' × '.join(t.factors)}, "
            f"sum-to-zero contrasts, type {t.ancova.ss_type} sums of squares, covariates "
            f"{', '.join(t.covariates) or 'none'}; N = {t.ancova.n}, residual df = "
            f"{t.ancova.df_resid}, R² = {t.ancova.r2:.2f}{paper_fit}. "
            "Type III tests each effect at the unweighted cell means adjusted for all other "
            "terms and the covariates (SPSS GLM's default, the form the paper reports). Like "
            f"the paper's, this model treats the {t.ancova.n} times as independent given the "
            "covariates; the repeated-measures ANOVA below models the participant instead."
        )
        if not with_paper:
            sec.paragraphs.append(_no_paper_values(res))
        sec.tables.append(
            Table(
                "Factorial ANOVA with covariates (as in the paper)",
                _anova_table(t.ancova.table, "timing_ancova", s, with_paper),
                _assumes("timing_ancova"),
            )
        )
        if t.mixed is not None:
            m = t.mixed
            sec.tables.append(
                Table(
                    "Linear mixed model with a random intercept per participant (reviewer's form)",
                    _rm_table(m.table, "timing_mixed", s).assign(
                        df=[
                            f"{_df(a)}, {_df(b)}"
                            for a, b in zip(m.table["df1"], m.table["df2"], strict=True)
                        ]
                    ),
                    f"Same fixed effects and covariates; REML (residual variance profiled, as lme4): participant "
                    f"variance {fmt(m.var_subject, 3)}, residual variance {fmt(m.var_resid, 3)} "
                    f"(ICC {fmt(m.icc, 2)}); type III Wald F on {m.df_method} df; partial η² from "
                    f"F and df. {_assumes('timing_mixed')}",
                )
            )
            est = m.estimates
            sec.tables.append(
                Table(
                    "Mixed-model estimates (Satterthwaite t, 95% CI)",
                    pd.DataFrame(
                        {
                            "term": est["term"],
                            "contrast": est["contrast"],
                            "estimate": est["estimate"].map(lambda v: fmt(v, 3)),
                            "SE": est["se"].map(lambda v: fmt(v, 3)),
                            "t": [
                                f"t({_df(d)}) = {fmt(v)}"
                                for d, v in zip(est["df"], est["t"], strict=True)
                            ],
                            "p": est["p"].map(fmt_p),
                            "95% CI": [
                                _ci(a, b, 3)
                                for a, b in zip(est["ci_low"], est["ci_high"], strict=True)
                            ],
                        }
                    ),
                    "Factor contrasts are differences of unweighted marginal "
                    "means (seconds); covariates are slopes per unit.",
                )
            )
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
        sec.tables.append(Table("Main effects as mean differences (s)", effects))
        sec.tables.append(
            Table(
                f"Repeated-measures ANOVA ({t.rm.n_subjects} participants)",
                _rm_table(t.rm.table, "timing_rm", s),
                "Subjects as error strata: each effect's error df is its df "
                "times (n - 1); the paper reports only the covariate model "
                f"above. {_assumes('timing_rm')}",
            )
        )
        c = t.comparisons
        if len(c):
            comp = s[
                s.analysis.isin(
                    [
                        "timing_posthoc",
                        "timing_planned",
                        "timing_pairwise",
                        "timing_posthoc_subject",
                    ]
                )
            ]
            comp = comp.reset_index(drop=True)
            paired = pd.DataFrame(
                {
                    "family": c["family"],
                    "comparison": c["comparison"],
                    "t": [
                        f"t({fmt(d, 0)}) = {fmt(v)}" for d, v in zip(c["df"], c["t"], strict=True)
                    ],
                    "p": c["p"].map(fmt_p),
                    "p (Bonferroni)": c["p_bonf"].map(fmt_p),
                    "mean diff (s)": c["mean_diff"].map(fmt),
                    "95% CI (unadjusted)": [
                        _ci(a, b) for a, b in zip(c["ci_low"], c["ci_high"], strict=True)
                    ],
                    "Bonferroni CI": [
                        _ci(a, b) for a, b in zip(c["ci_low_bonf"], c["ci_high_bonf"], strict=True)
                    ],
                    "d_z": c["d_z"].map(fmt),
                    "form": c["analysis"].map(
                        {
                            "timing_posthoc": "as in the paper",
                            "timing_planned": "as in the paper",
                            "timing_posthoc_subject": "reviewer",
                            "timing_pairwise": "reviewer",
                        }
                    ),
                }
            )
            if with_paper:
                paired["paper |t|"] = comp["paper_value"].map(fmt)
            sec.tables.append(
                Table(
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
            )
        summ = t.summary.copy()
        sec.tables.append(
            Table(
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
        )
        out.append(sec)
    if res.correlations is not None:
        sec = Section("Preferences")
        c = res.correlations
        sec.paragraphs.append(
            "Preference for the aggressive run (-3..+3) per participant and task against the "
            "time advantage of aggressive (timid minus aggressive duration), and each rating's "
            "aggressive-minus-timid difference against the preference."
        )
        corr = pd.DataFrame(
            {
                "measure": c["measure"],
                "versus": c["versus"],
                "r": [f"r({fmt(d, 0)}) = {fmt(r)}" for d, r in zip(c["df"], c["r"], strict=True)],
                "p": c["p"].map(fmt_p),
                "95% CI": [_ci(a, b) for a, b in zip(c["ci_low"], c["ci_high"], strict=True)],
            }
        )
        if res.paper_comparable["preference"]:
            corr["paper r"] = s[s.analysis == "preference"]["paper_value"].map(fmt).to_numpy()
        else:
            sec.paragraphs.append(_no_paper_values(res))
        sec.tables.append(
            Table("Pearson correlations (as in the paper)", corr, _assumes("preference"))
        )
        rc = res.rm_correlations
        if rc is not None:
            sec.tables.append(
                Table(
                    "Repeated-measures correlations (reviewer's form)",
                    pd.DataFrame(
                        {
                            "measure": rc["measure"],
                            "versus": rc["versus"],
                            "r_rm": [
                                f"r({fmt(d, 0)}) = {fmt(r)}"
                                for d, r in zip(rc["df"], rc["r"], strict=True)
                            ],
                            "p": rc["p"].map(fmt_p),
                            "95% CI": [
                                _ci(a, b) for a, b in zip(rc["ci_low"], rc["ci_high"], strict=True)
                            ],
                            "pairs": rc["n"],
                            "participants": rc["n_subjects"],
                        }
                    ),
                    _assumes("preference_rmcorr"),
                )
            )
        out.append(sec)
    if res.prediction_summary is not None:
        sec = Section("Prediction (section 5.2)")
        p = res.prediction
        with_paper = res.paper_comparable["prediction"]
        sec.paragraphs.append(
            "Every logged user-target trajectory replayed through app.blending's predictors "
            f"({', '.join(res.prediction_summary['predictor'].unique())}); success rate = share "
            "of ticks predicting the target; time to the first lasting correct prediction from "
            "the trial's start."
        )
        if choices:
            sec.paragraphs.append(
                "Predictor parameters: " + "; ".join(c.describe() for c in choices) + "."
            )
        if p is not None:
            paper_fit = (
                " (the paper reports R² = 0.9 for N = 128, residual df = 112)" if with_paper else ""
            )
            sec.paragraphs.append(
                f"Factorial ANOVA (type {p.ss_type} SS): N = {p.n}, residual df = "
                f"{p.df_resid}, R² = {p.r2:.2f}{paper_fit}."
            )
        if not with_paper:
            sec.paragraphs.append(
                _no_paper_values(res, "design" if not res.paper_design else "predictors")
            )
        ps = res.prediction_summary
        sec.tables.append(
            Table(
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
        )
        if p is not None:
            sec.tables.append(
                Table(
                    "Factorial ANOVA on the success rate (as in the paper)",
                    _anova_table(p.table, "prediction_anova", s, with_paper),
                    _assumes("prediction_anova"),
                )
            )
        if res.prediction_rm is not None:
            sec.tables.append(
                Table(
                    f"Repeated-measures ANOVA on the success rate, participant x condition x "
                    f"predictor ({res.prediction_rm.n_subjects} participants; reviewer's form)",
                    _rm_table(res.prediction_rm.table, "prediction_rm", s),
                    _assumes("prediction_rm"),
                )
            )
        sec.figures += [f for k, f in figures.items() if k == "fig9"]
        out.append(sec)
    if res.timing is not None:
        wide = res.timing.cells.pivot_table(
            index="participant", columns=["task", "mode"], values="duration_s", observed=True
        )
        wide.columns = [f"{t} {m}" for t, m in wide.columns]
        out.append(
            Section(
                "Appendix: time per participant and cell (s)",
                tables=[Table("Analysed durations", wide.map(fmt).reset_index())],
            )
        )
    if res.notes:
        out.append(Section("Notes on the data", paragraphs=list(res.notes)))
    return out


def _example_trial(res: StudyResults) -> Any:
    ev = res.evals
    if ev is None or ev.empty or ev["predictor"].nunique() < 2:
        return None
    w = ev.pivot_table(index="trial_id", columns="predictor", values="success_rate")
    a, b = list(dict.fromkeys(ev["predictor"]))[:2]
    tid = (w[b] - w[a]).idxmax()
    return res.cells[res.cells["trial_id"] == tid].iloc[0]


def _mode_order(res: StudyResults, proto: ProtocolInfo | None) -> tuple[str, ...]:
    if proto is not None and proto.factors.get("mode"):
        return tuple(proto.factors["mode"])
    if res.timing is not None:
        return tuple(res.timing.levels["mode"])
    return ("timid", "aggressive")


def _points(tables: StudyTables) -> int:
    """The rating scale's length: the largest answer seen, at least 7."""
    values = pd.to_numeric(tables.ratings.get("value", pd.Series(dtype=float)), errors="coerce")
    return max(7, int(values.max())) if values.notna().any() else 7


def _figures(
    res: StudyResults,
    tables: StudyTables,
    proto: ProtocolInfo | None,
    out: Path,
    predictors: Mapping[str, Mapping[str, Any]],
    *,
    successful_only: bool = False,
) -> dict[str, figs.SavedFigure]:
    made: dict[str, figs.SavedFigure] = {}
    if proto is not None and proto.arbitrations:
        made["fig7"] = figs.save(
            figs.arbitration_figure(proto.arbitrations, rate_hz=proto.rate_hz),
            out,
            "fig7_arbitration",
            "Fig. 7: arbitration α(c) of each mode",
        )
    modes = list(_mode_order(res, proto))
    if not res.cells.empty:
        g = res.cells.groupby(["task", "mode"])["duration_s"]
        time = (g.mean().rename("mean").to_frame().join(g.sem().rename("se"))).reset_index()
        pref, reference = preference_summary(tables)
        runs = "successful runs" if successful_only else "all completed runs"
        made["fig8"] = figs.save(
            figs.timing_preference_figure(
                time,
                pref,
                modes=modes,
                reference=reference,
                time_label=f"time to complete (s), {runs}",
            ),
            out,
            "fig8_time_preference",
            f"Fig. 8: time ({runs}) and preference per task (mean ± SE; no bar without an SE)",
        )
    ratings = rating_summary(tables.ratings, modes=modes)
    if not ratings.empty:
        made["fig8_ratings"] = figs.save(
            figs.ratings_figure(ratings, modes=modes, points=_points(tables)),
            out,
            "fig8_ratings",
            "Fig. 8: ratings per task and mode after each run (mean ± SE)",
        )
    row = _example_trial(res)
    if row is not None and res.evals is not None:
        names, pts, target = trial_goals(row)
        tid = row["trial_id"]
        t, xyz, moved = trial_trajectories(tables.samples[tables.samples["trial_id"] == tid])[tid]
        moves = goal_moves(moved, names, tid)
        reps = {
            name: replay(pts, xyz, make_predictor(cfg, pts), t=t, target=target, moves=moves)
            for name, cfg in list(predictors.items())[:2]
        }
        title = f"trial {row['trial_id']} ({row['participant']}, {row['task']}, {row['mode']})"
        made["fig9"] = figs.save(
            figs.prediction_figure(res.evals, reps, pts, names, target, title, modes=modes),
            out,
            "fig9_prediction",
            "Fig. 9: prediction success (mean ± SE) and one trajectory "
            "(green = correct, red = wrong; arrow = first lasting correct point)",
        )
    return made


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
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
    return _jsonable(doc)


def write_report(
    tables: StudyTables,
    out_dir: str | Path,
    *,
    protocol_path: str | Path | None = None,
    predictors: Mapping[str, Mapping[str, Any]] | None = None,
    successful_only: bool = False,
) -> ReportFiles:
    """Analyse ``tables`` and write report.html, report.md, results.json and figures/.

    Fig. 7, the protocol hash, the factor levels and the replayed predictors come from the
    protocol kept with the data (the store's text or the export's protocol.toml); the file
    ``protocol_path`` is read when the source keeps none (default: protocols/dragan2013.toml,
    and then a differing default file is not mentioned).

    ``predictors``: the configs to replay; by default the paper's two (amnesic, memory-based
    with eq. 9's squared velocity), each replaced by the protocol's table of the same kind if
    it has one."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    proto: ProtocolInfo | None = None
    proto_notes: list[str] = []
    try:
        proto = load_protocol_info(
            protocol_path or DEFAULT_PROTOCOL,
            stored=tables.source,
            explicit=protocol_path is not None,
        )
        proto_notes += list(proto.notes)
    except AnalysisError as e:
        proto_notes.append(f"protocol not read (no Fig. 7, no hash): {e}")
    if predictors is not None:
        choices = [
            PredictorChoice(n, dict(c), "given by the caller") for n, c in predictors.items()
        ]
    else:
        predictors, choices = protocol_predictors(proto.prediction if proto else None, PREDICTORS)
    res = analyse(
        tables,
        predictors=predictors,
        successful_only=successful_only,
        levels=proto.factors if proto is not None else None,
    )
    res.notes = proto_notes + res.notes
    figures = _figures(
        res, tables, proto, out / "figures", predictors, successful_only=successful_only
    )
    meta = {
        "title": TITLE,
        "source": tables.source,
        "generated_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "software": software_info(),
        "protocol": {
            "path": proto.path if proto else None,
            "id": proto.study_id if proto else None,
            "content_hash": proto.content_hash if proto else None,
            "store_hash": tables.protocol_hash,
        },
        "participants": int(res.cells["participant"].nunique()) if not res.cells.empty else 0,
        "predictors": {c.name: {"config": c.config, "source": c.source} for c in choices},
    }
    if (
        tables.protocol_hash
        and proto
        and proto.content_hash
        and tables.protocol_hash != proto.content_hash
    ):
        res.notes.insert(
            0,
            "the protocol file's hash differs from the one recorded with the "
            "data: pass the protocol the study ran with (--protocol)",
        )
    modes = proto.factors.get("mode") if proto is not None else None
    extra = [
        s
        for s in (
            decoy_section(tables),
            success_section(tables, modes=modes, tests=res.inferential),
            contact_section(tables),
        )
        if s is not None
    ]
    sections = _sections(
        res,
        figures,
        tables,
        choices,
        modes=modes,
        successful_only=successful_only,
        extra=extra,
    )
    html_path, md_path, json_path = out / "report.html", out / "report.md", out / "results.json"
    html_path.write_text(render_html(sections, meta), encoding="utf-8")
    md_path.write_text(render_markdown(sections, meta), encoding="utf-8")
    json_path.write_text(
        json.dumps(
            results_document(
                res,
                meta,
                success=(
                    success_summary(tables.trials, modes=modes),
                    success_comparisons(tables.trials, modes=modes)
                    if res.inferential
                    else pd.DataFrame(),
                ),
            ),
            indent=1,
            allow_nan=False,
        ),
        encoding="utf-8",
    )
    paths = tuple(p for f in figures.values() for p in (f.png, f.svg))
    return ReportFiles(
        html=html_path, markdown=md_path, results_json=json_path, figures=paths, results=res
    )

"""The paper's timing analysis (section 5.1) on one row per participant, task and mode.

1. Factorial ANOVA with covariates: ``duration ~ difficulty * correctness * mode`` (sum-to-zero
   contrasts) ``+ training_time_s + baseline_rating + tasks_completed``, type III SS, R^2 -
   F(1, 53) with 8 participants.
2. Repeated-measures ANOVA on the same cells (subjects as error strata): F(1, 7), np2.
3. Paired t-tests, Bonferroni within each family, d_z and 95% CIs: post-hoc aggressive-and-wrong
   against each other aggressiveness x correctness situation (pairs = participant x difficulty,
   t(15)); planned timid vs aggressive on Hard&Right and on Easy&Wrong (t(7)).

Other designs (a protocol with other levels, e.g. three modes, or a factor with one level) get
the same models on the factors that vary, and pairwise mode comparisons within each task.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.anova import FactorialAnovaResult, covariate_anova
from analysis.design import cell_means
from analysis.errors import AnalysisError, DesignError
from analysis.load import COVARIATES
from analysis.mixed import MixedModelResult, mixed_anova
from analysis.posthoc import Comparison, paired_comparisons
from analysis.rm_anova import RMAnovaResult, rm_anova

FACTORS = ("difficulty", "correctness", "mode")
LEVELS = {
    "difficulty": ("easy", "hard"),
    "correctness": ("right", "wrong"),
    "mode": ("timid", "aggressive"),
}
"""The paper's design; its levels also give the order of known levels in other designs."""


@dataclass(frozen=True)
class TimingAnalysis:
    cells: pd.DataFrame  # the analysed rows (complete participants only)
    ancova: FactorialAnovaResult  # factorial ANOVA with covariates (type III)
    rm: RMAnovaResult  # repeated-measures ANOVA
    comparisons: pd.DataFrame  # paired t-tests (posthoc.COLUMNS + analysis)
    summary: pd.DataFrame  # task x mode: mean, se, n of duration_s
    main_effects: pd.DataFrame  # effect, factor, contrast, mean_low, mean_high, mean_diff
    factors: tuple[str, ...]  # the factors that vary in the data
    levels: dict[str, tuple[str, ...]]
    covariates: tuple[str, ...]
    notes: tuple[str, ...]
    mixed: MixedModelResult | None = None  # the covariate model with a random intercept

    @property
    def paper_design(self) -> bool:
        return self.levels == {f: LEVELS[f] for f in FACTORS}


def design_levels(
    cells: pd.DataFrame, levels: Mapping[str, Sequence[str]] | None = None
) -> dict[str, tuple[str, ...]]:
    """Levels present per factor, in the given (protocol) order, else the paper's, else sorted."""
    out = {}
    for f in FACTORS:
        present = list(dict.fromkeys(cells[f].astype(str)))
        order = list((levels or {}).get(f, ())) + list(LEVELS[f])
        known = [lv for lv in dict.fromkeys(order) if lv in present]
        out[f] = tuple(known + sorted(lv for lv in present if lv not in known))
    return out


def usable_covariates(cells: pd.DataFrame, wanted: Sequence[str]) -> tuple[list[str], list[str]]:
    """Covariates present and varying; notes for each one left out and why."""
    keep, notes = [], []
    for c in wanted:
        if c not in cells.columns or cells[c].isna().all():
            notes.append(f"covariate {c!r} is not in the data and was left out")
        elif cells[c].isna().any():
            notes.append(f"covariate {c!r} has missing values and was left out")
        elif np.ptp(cells[c].to_numpy(dtype=float)) == 0:
            notes.append(f"covariate {c!r} is constant and was left out")
        else:
            keep.append(c)
    return keep, notes


def summarise(cells: pd.DataFrame, value: str) -> pd.DataFrame:
    """Mean, standard error (sd / sqrt n) and n per task and mode."""
    g = cells.groupby(["task", "difficulty", "correctness", "mode"], observed=True)[value]
    out = g.agg(["mean", "std", "count"]).reset_index()
    out["se"] = out["std"] / np.sqrt(out["count"])
    return out.rename(columns={"count": "n"}).drop(columns="std")


def _paper_comparisons(cells: pd.DataFrame) -> list[Comparison]:
    w = cells.pivot_table(
        index="participant", columns=list(FACTORS), values="duration_s", observed=True
    )

    def col(dif: str, cor: str, mode: str) -> np.ndarray:
        return w[(dif, cor, mode)].to_numpy()

    def both(cor: str, mode: str) -> np.ndarray:  # pairs = participant x difficulty
        return np.concatenate([col("easy", cor, mode), col("hard", cor, mode)])

    def mean(cor: str, mode: str) -> np.ndarray:  # one value per participant
        return (col("easy", cor, mode) + col("hard", cor, mode)) / 2

    family = "post-hoc: aggressive & wrong vs each other situation"
    subject_family = "post-hoc on participant means: aggressive & wrong vs each other situation"
    planned = "planned: timid vs aggressive per task"
    return [
        Comparison(
            family,
            "aggressive&wrong - timid&wrong (aggressive vs timid when wrong)",
            both("wrong", "aggressive"),
            both("wrong", "timid"),
        ),
        Comparison(
            family,
            "aggressive&wrong - aggressive&right",
            both("wrong", "aggressive"),
            both("right", "aggressive"),
        ),
        Comparison(
            family,
            "aggressive&wrong - timid&right",
            both("wrong", "aggressive"),
            both("right", "timid"),
        ),
        Comparison(
            planned,
            "Hard&Right: aggressive - timid",
            col("hard", "right", "aggressive"),
            col("hard", "right", "timid"),
        ),
        Comparison(
            planned,
            "Easy&Wrong: aggressive - timid",
            col("easy", "wrong", "aggressive"),
            col("easy", "wrong", "timid"),
        ),
        Comparison(
            subject_family,
            "aggressive&wrong - timid&wrong (aggressive vs timid when wrong)",
            mean("wrong", "aggressive"),
            mean("wrong", "timid"),
        ),
        Comparison(
            subject_family,
            "aggressive&wrong - aggressive&right",
            mean("wrong", "aggressive"),
            mean("right", "aggressive"),
        ),
        Comparison(
            subject_family,
            "aggressive&wrong - timid&right",
            mean("wrong", "aggressive"),
            mean("right", "timid"),
        ),
    ]


def _pairwise_mode_comparisons(cells: pd.DataFrame, modes: Sequence[str]) -> list[Comparison]:
    w = cells.pivot_table(
        index="participant", columns=["task", "mode"], values="duration_s", observed=True
    )
    out = []
    for task in dict.fromkeys(cells["task"]):
        for a, b in itertools.combinations(modes, 2):
            if (task, a) in w.columns and (task, b) in w.columns:
                out.append(
                    Comparison(
                        f"pairwise: modes within {task}",
                        f"{task}: {b} - {a}",
                        w[(task, b)].to_numpy(),
                        w[(task, a)].to_numpy(),
                    )
                )
    return out


def _analysis_of(family: str) -> str:
    if family.startswith("post-hoc on participant means"):
        return "timing_posthoc_subject"
    if family.startswith("post-hoc"):
        return "timing_posthoc"
    return "timing_planned" if family.startswith("planned") else "timing_pairwise"


def timing_analysis(
    cells: pd.DataFrame,
    *,
    covariates: Sequence[str] = COVARIATES,
    levels: Mapping[str, Sequence[str]] | None = None,
) -> TimingAnalysis:
    """Run the section 5.1 analyses on ``task_cells`` output (see the module docstring).

    ``levels``: the protocol's factor levels (their order is kept); default: the paper's.
    """
    lv = design_levels(cells, levels)
    factors = tuple(f for f in FACTORS if len(lv[f]) >= 2)
    if not factors:
        raise DesignError(
            "no factor of difficulty, correctness and mode has two levels in the "
            "data; there is nothing to compare"
        )
    data = cells.copy()
    for f in FACTORS:
        data[f] = pd.Categorical(data[f].astype(str), categories=list(lv[f]))
    complete = cell_means(
        data, dv="duration_s", subject="participant", within=factors, drop_incomplete=True
    )
    notes = list(complete.notes)
    data = data[data["participant"].isin(set(complete.subjects))].reset_index(drop=True)
    covs, cov_notes = usable_covariates(data, covariates)
    notes += cov_notes
    rm = rm_anova(data, dv="duration_s", subject="participant", within=factors)
    ancova = covariate_anova(
        data, dv="duration_s", subject="participant", within=factors, covariates=covs
    )
    mixed = None
    try:
        mixed = mixed_anova(
            data, dv="duration_s", subject="participant", factors=factors, covariates=covs
        )
        notes += [f"mixed model: {n}" for n in mixed.notes]
    except (AnalysisError, np.linalg.LinAlgError) as e:  # a failed fit (or singular) stays a note
        notes.append(f"mixed model skipped: {e}")
    marg = []
    for f in factors:
        m = data.groupby(f, observed=True)["duration_s"].mean()
        first = lv[f][0]
        for other in lv[f][1:]:
            marg.append(
                {
                    "effect": f if len(lv[f]) == 2 else f"{f} ({other} - {first})",
                    "factor": f,
                    "contrast": f"{other} - {first}",
                    "mean_low": m[first],
                    "mean_high": m[other],
                    "mean_diff": m[other] - m[first],
                }
            )
    paper = lv == {f: LEVELS[f] for f in FACTORS}
    specs = _paper_comparisons(data) if paper else _pairwise_mode_comparisons(data, lv["mode"])
    comparisons = paired_comparisons(specs) if specs else pd.DataFrame()
    if len(comparisons):
        comparisons.insert(0, "analysis", comparisons["family"].map(_analysis_of))
    if not paper:
        notes.append(
            "the design differs from the paper's 2 x 2 x 2 ("
            + "; ".join(f"{f}: {', '.join(v)}" for f, v in lv.items())
            + "): models on the factors that vary, pairwise mode comparisons per task"
        )
    return TimingAnalysis(
        cells=data,
        ancova=ancova,
        rm=rm,
        comparisons=comparisons,
        summary=summarise(data, "duration_s"),
        main_effects=pd.DataFrame(marg),
        factors=factors,
        levels=lv,
        covariates=tuple(covs),
        notes=tuple(dict.fromkeys(notes + list(ancova.notes))),
        mixed=mixed,
    )

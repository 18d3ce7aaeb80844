"""The paper's timing analysis (section 5.1) on one row per participant, task and mode.

1. Factorial ANOVA with covariates: ``duration ~ difficulty * correctness * mode`` (sum-to-zero
   contrasts) ``+ training_time_s + baseline_rating + tasks_completed``, type III SS, R^2 -
   F(1, 53) with 8 participants.
2. Repeated-measures ANOVA on the same cells (subjects as error strata): F(1, 7), np2.
3. Paired t-tests, Bonferroni within each family, d_z and 95% CIs: post-hoc aggressive-and-wrong
   against each other aggressiveness x correctness situation (pairs = participant x difficulty,
   t(15)); planned timid vs aggressive on Hard&Right and on Easy&Wrong (t(7)).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.anova import FactorialAnovaResult, covariate_anova
from analysis.design import cell_means
from analysis.load import COVARIATES
from analysis.posthoc import Comparison, paired_comparisons
from analysis.rm_anova import RMAnovaResult, rm_anova

FACTORS = ("difficulty", "correctness", "mode")
LEVELS = {"difficulty": ("easy", "hard"), "correctness": ("right", "wrong"),
          "mode": ("timid", "aggressive")}


@dataclass(frozen=True)
class TimingAnalysis:
    cells: pd.DataFrame            # the analysed rows (complete participants only)
    ancova: FactorialAnovaResult   # factorial ANOVA with covariates (type III)
    rm: RMAnovaResult              # repeated-measures ANOVA
    comparisons: pd.DataFrame      # paired t-tests (posthoc.COLUMNS)
    summary: pd.DataFrame          # task x mode: mean, se, n of duration_s
    main_effects: pd.DataFrame     # mean differences of the three factors, seconds
    covariates: tuple[str, ...]
    notes: tuple[str, ...]


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


def _comparisons(cells: pd.DataFrame) -> pd.DataFrame:
    w = cells.pivot_table(index="participant", columns=list(FACTORS), values="duration_s")

    def col(dif: str, cor: str, mode: str) -> np.ndarray:
        return w[(dif, cor, mode)].to_numpy()

    def both(cor: str, mode: str) -> np.ndarray:  # pairs = participant x difficulty
        return np.concatenate([col("easy", cor, mode), col("hard", cor, mode)])

    family = "post-hoc: aggressive & wrong vs each other situation"
    specs = [
        Comparison(family, "aggressive&wrong - timid&wrong (aggressive vs timid when wrong)",
                   both("wrong", "aggressive"), both("wrong", "timid")),
        Comparison(family, "aggressive&wrong - aggressive&right",
                   both("wrong", "aggressive"), both("right", "aggressive")),
        Comparison(family, "aggressive&wrong - timid&right",
                   both("wrong", "aggressive"), both("right", "timid")),
        Comparison("planned: timid vs aggressive per task", "Hard&Right: aggressive - timid",
                   col("hard", "right", "aggressive"), col("hard", "right", "timid")),
        Comparison("planned: timid vs aggressive per task", "Easy&Wrong: aggressive - timid",
                   col("easy", "wrong", "aggressive"), col("easy", "wrong", "timid")),
    ]
    return paired_comparisons(specs)


def timing_analysis(cells: pd.DataFrame, *,
                    covariates: Sequence[str] = COVARIATES) -> TimingAnalysis:
    """Run the section 5.1 analyses on ``task_cells`` output (see the module docstring)."""
    data = cells.copy()
    for f, lv in LEVELS.items():
        data[f] = pd.Categorical(data[f], categories=list(lv))
    complete = cell_means(data, dv="duration_s", subject="participant", within=FACTORS,
                          drop_incomplete=True)
    notes = list(complete.notes)
    data = data[data["participant"].isin(set(complete.subjects))].reset_index(drop=True)
    covs, cov_notes = usable_covariates(data, covariates)
    notes += cov_notes
    rm = rm_anova(data, dv="duration_s", subject="participant", within=FACTORS)
    ancova = covariate_anova(data, dv="duration_s", subject="participant", within=FACTORS,
                             covariates=covs)
    marg = []
    for f, (lo, hi) in LEVELS.items():
        m = data.groupby(f, observed=True)["duration_s"].mean()
        marg.append({"factor": f, "contrast": f"{hi} - {lo}", "mean_low": m[lo],
                     "mean_high": m[hi], "mean_diff": m[hi] - m[lo]})
    return TimingAnalysis(
        cells=data, ancova=ancova, rm=rm, comparisons=_comparisons(data),
        summary=summarise(data, "duration_s"), main_effects=pd.DataFrame(marg),
        covariates=tuple(covs), notes=tuple(dict.fromkeys(notes + list(ancova.notes))),
    )

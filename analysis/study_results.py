"""What ``analyse`` found on one study (:class:`StudyResults`), and whether the design and the
predictors are the paper's (so that its published values are comparable)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from analysis.anova import FactorialAnovaResult
from analysis.factor_analysis import FactorAnalysis
from analysis.rm_anova import RMAnovaResult
from analysis.statistics_rows import STAT_COLUMNS
from analysis.timing import FACTORS, LEVELS, TimingAnalysis, design_levels


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
    factors: FactorAnalysis | None = None  # a design other than the paper's, by factor name

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

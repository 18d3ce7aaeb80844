"""The analysis of any design by factor name: per measure (the run's duration and every Likert
item rated after a run) the split-plot ANOVA on participant cell means, the random-intercept
mixed model on every run, and the post-hoc comparisons; the ratings by condition.

The models use the declared factors that vary in the data: within factors as repeated
measures, between factors as between-subject terms (:mod:`analysis.split_plot`; the mixed model
:mod:`analysis.mixed` with the between factors as fixed effects, whose Satterthwaite df are then
about ``n - g``). Runs of one condition (e.g. a condition's several tasks) are averaged per
participant; participants lacking a condition are left out of the ANOVA and the post-hoc tests
(with a note), not of the mixed model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.errors import AnalysisError
from analysis.factor_design import FactorDesign
from analysis.item_ratings import ratings_by_condition
from analysis.mixed import MixedModelResult, mixed_anova
from analysis.pairwise import pairwise_comparisons
from analysis.split_plot import SplitPlotResult, split_plot_anova

DURATION = "duration_s"


@dataclass(frozen=True)
class MeasureAnalysis:
    """One measure's models: ``anova`` and ``mixed`` are ``None`` when they could not run
    (``notes`` says why); ``posthoc`` has :data:`analysis.pairwise.COLUMNS`."""

    measure: str
    anova: SplitPlotResult | None
    mixed: MixedModelResult | None
    posthoc: pd.DataFrame
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class FactorAnalysis:
    """The design, the analysed runs, each measure's models and the ratings by condition."""

    design: FactorDesign
    cells: pd.DataFrame
    measures: dict[str, MeasureAnalysis]
    ratings: pd.DataFrame
    items: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default_factory=tuple)


def measure_analysis(cells: pd.DataFrame, design: FactorDesign, measure: str) -> MeasureAnalysis:
    """The split-plot ANOVA, the mixed model and the post-hoc tests of one measure."""
    data = cells.assign(**{measure: pd.to_numeric(cells[measure], errors="coerce")})
    notes: list[str] = []
    anova = None
    posthoc = pd.DataFrame()
    if not design.within:
        notes.append("no within-subject factor varies: no repeated-measures ANOVA")
    else:
        try:
            anova = split_plot_anova(
                data,
                dv=measure,
                subject="participant",
                within=design.within,
                between=design.between,
                drop_incomplete=True,
            )
            # a condition's several runs (its tasks) are averaged by design: no note for that
            notes += [n for n in anova.notes if "more than one row" not in n]
            posthoc = pairwise_comparisons(anova)
        except AnalysisError as e:
            notes.append(f"ANOVA skipped: {e}")
    mixed = None
    try:
        mixed = mixed_anova(
            data, dv=measure, subject="participant", factors=[*design.between, *design.within]
        )
        notes += [f"mixed model: {n}" for n in mixed.notes]
    except (AnalysisError, np.linalg.LinAlgError) as e:
        notes.append(f"mixed model skipped: {e}")
    return MeasureAnalysis(measure, anova, mixed, posthoc, tuple(notes))


def factor_analysis(
    cells: pd.DataFrame,
    design: FactorDesign,
    *,
    items: Sequence[str] = (),
    tests: bool = True,
) -> FactorAnalysis:
    """Every measure's models (with ``tests``) and the ratings by condition of ``items`` on
    :func:`analysis.factor_design.condition_cells` output (module docstring)."""
    items = tuple(i for i in items if i in cells.columns)
    measures: dict[str, MeasureAnalysis] = {}
    notes: list[str] = []
    if design.dropped:
        notes.append(
            "declared factor(s) with one level in the data, left out of the models: "
            + "; ".join(design.dropped)
        )
    if tests:
        for m in (DURATION, *items):
            if pd.to_numeric(cells[m], errors="coerce").notna().any():
                measures[m] = measure_analysis(cells, design, m)
                notes += [f"{m}: {n}" for n in measures[m].notes]
    return FactorAnalysis(
        design=design,
        cells=cells,
        measures=measures,
        ratings=ratings_by_condition(cells, items, design),
        items=items,
        notes=tuple(notes),
    )

"""A study's design by factor name: which factors vary within and which between subjects, and
their levels as the data have them, in the protocol's order.

A condition is one combination of the within factors' levels (``prod(levels)`` of them); a
between factor splits the participants into groups. The paper's design is difficulty x
correctness x mode, all within (:func:`is_paper_factors`): its report keeps the paper's
sections; any other set of factors gets the general ones.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import pandas as pd

from analysis.errors import DesignError
from analysis.load import PAPER_FACTORS, task_cells

NO_LEVEL = ("", "none", "<NA>", "nan")
"""What a trial's factor column holds outside the design (training runs: mode "none", empty)."""


@dataclass(frozen=True)
class FactorDesign:
    """``factors``: every factor that varies in the data with its levels (declared order);
    ``between``: those varied between subjects; ``dropped``: declared factors with one level in
    the data (left out of the models, each with why)."""

    factors: dict[str, tuple[str, ...]]
    between: tuple[str, ...] = ()
    dropped: tuple[str, ...] = ()

    @property
    def within(self) -> tuple[str, ...]:
        return tuple(f for f in self.factors if f not in self.between)

    @property
    def conditions(self) -> list[tuple[str, ...]]:
        """Every combination of the within factors' levels (first factor slowest)."""
        return list(itertools.product(*(self.factors[f] for f in self.within)))

    def label(self, levels: Mapping[str, str]) -> str:
        """``"intent=shown, mode=timid"``: a condition (or group) by factor name."""
        return ", ".join(f"{f}={levels[f]}" for f in self.factors if f in levels)


def is_paper_factors(factors: Sequence[str], between: Sequence[str] = ()) -> bool:
    """The declared factors are the paper's three (any levels), all within subjects."""
    return set(factors) == set(PAPER_FACTORS) and len(factors) == 3 and not between


def factor_design(
    trials: pd.DataFrame,
    factors: Mapping[str, Sequence[str]] | Sequence[str],
    *,
    between: Sequence[str] = (),
) -> FactorDesign:
    """The design of the task trials of ``trials`` over the declared ``factors`` (a mapping to
    their levels in order, or names: levels as first seen). Levels absent from the data are
    left out; a factor left with one level is dropped with a note; a missing column raises."""
    declared = (
        {str(f): tuple(map(str, v)) for f, v in factors.items()}
        if isinstance(factors, Mapping)
        else {str(f): () for f in factors}
    )
    unknown = [b for b in between if b not in declared]
    if unknown:
        raise DesignError(
            f"between factor(s) {', '.join(unknown)} are not among the declared factors "
            f"({', '.join(declared)}); declare them in [factors]"
        )
    absent = [f for f in declared if f not in trials.columns]
    if absent:
        raise DesignError(
            f"the trials table has no column for the declared factor(s) {', '.join(absent)}; "
            "export the study again with this version (one column per declared factor)"
        )
    task = trials[trials["phase"] == "task"] if "phase" in trials.columns else trials
    kept: dict[str, tuple[str, ...]] = {}
    dropped = []
    for f, order in declared.items():
        present = [v for v in dict.fromkeys(task[f].astype(str)) if v not in NO_LEVEL]
        levels = [v for v in order if v in present] + [v for v in present if v not in order]
        if len(levels) >= 2:
            kept[f] = tuple(levels)
        else:
            dropped.append(f"{f} ({', '.join(levels) or 'no level'} in the data)")
    if not kept:
        raise DesignError(
            "no declared factor has two levels in the task trials; there is nothing to compare"
        )
    return FactorDesign(
        factors=kept, between=tuple(b for b in between if b in kept), dropped=tuple(dropped)
    )


def condition_cells(
    trials: pd.DataFrame, design: FactorDesign, *, successful_only: bool = False
) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """One row per participant, task and condition (the completed task trials; a cell run twice
    averaged), every factor column as a categorical in the design's order, and notes."""
    cells, notes = task_cells(
        trials, successful_only=successful_only, factors=tuple(design.factors)
    )
    cells = cells.copy()
    for f, levels in design.factors.items():
        cells[f] = pd.Categorical(cells[f].astype(str), categories=list(levels))
    outside = cells[list(design.factors)].isna().any(axis=1)
    if outside.any():
        notes = (*notes, f"{int(outside.sum())} task run(s) at levels outside the design left out")
        cells = cells[~outside].reset_index(drop=True)
    return cells, notes

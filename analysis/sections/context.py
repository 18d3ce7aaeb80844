"""What every report section is built from: :class:`ReportContext`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from analysis.load import StudyTables
from analysis.study_results import StudyResults

if TYPE_CHECKING:  # the figures module pulls in matplotlib; a section only passes them on
    from analysis.figures import SavedFigure
    from analysis.prediction_eval import PredictorChoice


@dataclass(frozen=True)
class ReportContext:
    """The results and the tables they came from, the figures drawn (by key: fig7, fig8,
    fig8_ratings, fig9), the predictors replayed, the protocol's mode order (``None``: the
    data's) and whether the durations are of successful runs only."""

    res: StudyResults
    tables: StudyTables
    figures: Mapping[str, SavedFigure]
    choices: Sequence[PredictorChoice] = ()
    modes: Sequence[str] | None = None
    successful_only: bool = False

"""A simulated participant's questionnaire answers, from what they experienced.

The answers see only :class:`~study.simulated.experience.RunExperience` values: a run's
duration ``T``, the mean disagreement ``Dbar`` between the user's input motion and the robot's
motion, and whether the object was picked up. References ``T0``, ``D0`` are the participant's
own training runs (the unassisted robot). With the participant's parameters (time weight
``w_t``, disagreement weight ``w_d``, control bias ``kappa``, failure penalty ``w_f``, generosity
``o``, answer noise ``sd``) and an item's emphasis ``(e_t, e_d, b)``:

    score(run) = - e_t w_t log(T / T0) - e_d w_d (1 + b kappa) (Dbar - D0) - w_f [not success]
    rating     = clip(round(m + s (o + score + sd z)), 1, k)          (m = (k + 1) / 2)
    preference = clip(round(m + s (g (U_2 - U_1) + sd z)), 1, k)      (1 = the first run)

where ``U`` is the score with full emphasis (1, 1, 1), ``g`` the participant's preference gain
(some exaggerate), ``s = (k - 1) / 6`` rescales a 7-point calibration to a k-point scale and
``z ~ N(0, 1)``. "Helpful" leans on time and ignores the control bias (users who preferred
control still admitted the aggressive robot helped more, section 5.1); "matched" leans on the
disagreement.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from study.simulated.errors import SimulationError
from study.simulated.experience import RunExperience
from study.simulated.population import QuestionnaireParams


@dataclass(frozen=True)
class ItemEmphasis:
    """How much an item's answer follows time (``e_t``) and disagreement (``e_d``), and whether
    the personal control bias applies (``bias``)."""

    time: float = 1.0
    disagreement: float = 1.0
    bias: float = 1.0


ITEM_EMPHASIS: dict[str, ItemEmphasis] = {
    "helpful": ItemEmphasis(time=1.0, disagreement=0.5, bias=0.0),
    "matched": ItemEmphasis(time=0.5, disagreement=1.0, bias=1.0),
    "teammate": ItemEmphasis(time=1.0, disagreement=1.0, bias=1.0),
}
_DEFAULT = ItemEmphasis()


class QuestionnaireModel:
    """One participant's answering: ``observe_training`` once, then ``rate`` and ``prefer``."""

    def __init__(self, params: QuestionnaireParams, *, rng: np.random.Generator) -> None:
        self.params = params
        self.rng = rng
        self.reference_s: float | None = None
        self.reference_disagreement = 0.0

    def observe_training(self, runs: Sequence[RunExperience]) -> None:
        """Set the references ``T0`` (geometric mean duration) and ``D0`` from training runs."""
        durations = [r.duration_s for r in runs if r.duration_s > 0]
        if durations:
            self.reference_s = math.exp(sum(math.log(d) for d in durations) / len(durations))
        if runs:
            self.reference_disagreement = sum(r.mean_disagreement for r in runs) / len(runs)

    def score(self, run: RunExperience, emphasis: ItemEmphasis = _DEFAULT) -> float:
        """``score(run)`` of the module docstring, in 7-point scale units."""
        p = self.params
        ref = self.reference_s if self.reference_s is not None else max(run.duration_s, 1e-3)
        log_time = math.log(max(run.duration_s, 1e-3) / ref)
        disagreement = run.mean_disagreement - self.reference_disagreement
        return (
            -emphasis.time * p.time_weight * log_time
            - emphasis.disagreement
            * p.disagreement_weight
            * (1.0 + emphasis.bias * p.control_bias)
            * disagreement
            - p.failure_penalty * (0.0 if run.success else 1.0)
        )

    def rate(
        self,
        item_ids: Sequence[str],
        runs: RunExperience | Sequence[RunExperience],
        *,
        points: int,
    ) -> dict[str, int]:
        """Answers to ``item_ids`` about one run (or the mean score over several, e.g. training)."""
        _check_points(points)
        group = [runs] if isinstance(runs, RunExperience) else list(runs)
        if not group:
            raise SimulationError("rate: need at least one run to rate; got none")
        out: dict[str, int] = {}
        for item in item_ids:
            emphasis = ITEM_EMPHASIS.get(item, _DEFAULT)
            score = sum(self.score(r, emphasis) for r in group) / len(group)
            raw = self.params.rating_offset + score + self.params.noise_sd * self._z()
            out[item] = _to_scale(raw, points=points)
        return out

    def prefer(self, first: RunExperience, second: RunExperience, *, points: int) -> int:
        """Preference between the two runs of a task: 1 = strongly the first, ``points`` the
        second."""
        _check_points(points)
        diff = self.score(second) - self.score(first)
        raw = self.params.preference_gain * diff + self.params.noise_sd * self._z()
        return _to_scale(raw, points=points)

    def _z(self) -> float:
        return float(self.rng.standard_normal())


def _check_points(points: int) -> None:
    if points < 2:
        raise SimulationError(f"a rating scale needs at least 2 points, got {points}")


def _to_scale(raw: float, *, points: int) -> int:
    """``clip(round(m + s raw), 1, k)`` with ``s = (k - 1) / 6``."""
    mid = (points + 1) / 2
    value = mid + (points - 1) / 6.0 * raw
    return int(min(max(round(value), 1), points))

"""The paper's two criteria for its arbitration modes, measured on a simulated population.

Dragan & Srinivasa (2013, section 4) chose the modes so that

(a) *timid* gives as little help as possible while the hard task is still completable:
    a timid setting passes when the share of its **hard** trials (both correctness levels,
    timid mode) that end in success is at least ``min_hard_completion``; among passing
    settings the one with the least help is chosen;
(b) *aggressive* gives as much help as possible while the user can still correct it when it is
    wrong: an aggressive setting passes when the share of its **wrong**-prediction trials
    (aggressive mode) that the user still completes is at least ``min_wrong_corrected`` and the
    time lost to the wrong prediction -- mean duration of successful wrong trials minus that of
    successful right trials, same mode, both difficulties -- is at most ``max_time_lost_s``;
    among passing settings the one with the most help is chosen.

"Help" is the area under the arbitration curve (``Setting.help``). Only completed trials of the
main phase count (training is unassisted); a trial redone after a pause counts once, as its
final attempt.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from study.sweep.grid import AGGRESSIVE, TIMID, Setting

if TYPE_CHECKING:
    from study.store import Store

DEFAULT_MIN_HARD_COMPLETION = 0.8
DEFAULT_MIN_WRONG_CORRECTED = 0.8
DEFAULT_MAX_TIME_LOST_S = 10.0


@dataclass(frozen=True)
class Criteria:
    """The thresholds; stated in every output so a reader can re-judge the evidence."""

    min_hard_completion: float = DEFAULT_MIN_HARD_COMPLETION
    min_wrong_corrected: float = DEFAULT_MIN_WRONG_CORRECTED
    max_time_lost_s: float = DEFAULT_MAX_TIME_LOST_S

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class Measure:
    """One setting's evidence: what its participants did in the swept mode."""

    setting: Setting
    help: float
    participants: int
    trials: int
    """Trials that count for the setting's criterion (hard ones for timid, wrong for aggressive)."""
    rate: float
    """Timid: hard-task completion; aggressive: share of wrong trials completed."""
    time_lost_s: float | None
    """Aggressive only: mean successful wrong minus mean successful right duration, s."""
    passes: bool

    def row(self) -> dict[str, Any]:
        return {
            "mode": self.setting.mode,
            **dict(self.setting.params),
            "D": self.setting.D,
            "help": round(self.help, 4),
            "participants": self.participants,
            "trials": self.trials,
            "rate": round(self.rate, 4),
            "time_lost_s": None if self.time_lost_s is None else round(self.time_lost_s, 2),
            "passes": self.passes,
        }


def measure(store: Store, setting: Setting, *, saturation: float, criteria: Criteria) -> Measure:
    """Judge ``setting`` on the trials in ``store`` (one variant's store)."""
    final: dict[tuple[str, int], Any] = {}
    for t in store.trials():
        if t.phase == "training" or t.mode != setting.mode or t.status != "completed":
            continue
        key = (t.participant, t.step)
        if key not in final or t.attempt > final[key].attempt:
            final[key] = t
    trials = list(final.values())
    people = len({t.participant for t in trials})
    help_ = setting.help(saturation=saturation)
    if setting.mode == TIMID:
        judged = [t for t in trials if t.difficulty == "hard"]
        rate = _share(judged)
        return Measure(
            setting, help_, people, len(judged), rate, None, rate >= criteria.min_hard_completion
        )
    assert setting.mode == AGGRESSIVE
    wrong = [t for t in trials if t.correctness == "wrong"]
    right = [t for t in trials if t.correctness == "right"]
    rate = _share(wrong)
    lost = _mean_success_s(wrong) - _mean_success_s(right)
    lost_s = None if np.isnan(lost) else float(lost)
    passes = (
        rate >= criteria.min_wrong_corrected
        and lost_s is not None
        and lost_s <= criteria.max_time_lost_s
    )
    return Measure(setting, help_, people, len(wrong), rate, lost_s, passes)


def _share(trials: list[Any]) -> float:
    return float(np.mean([bool(t.success) for t in trials])) if trials else 0.0


def _mean_success_s(trials: list[Any]) -> float:
    times = [t.duration_s for t in trials if t.success and t.duration_s is not None]
    return float(np.mean(times)) if times else float("nan")


def choose(measures: list[Measure], mode: str) -> Measure | None:
    """The paper's pick among passing settings at the protocol's ``D``: least help for timid,
    most for aggressive (ties: the earlier setting in the grid); ``None`` when none passes."""
    passing = [m for m in measures if m.setting.mode == mode and m.passes and m.setting.D is None]
    if not passing:
        return None
    if mode == TIMID:
        return min(passing, key=lambda m: m.help)
    return max(passing, key=lambda m: m.help)

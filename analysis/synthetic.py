"""Synthetic tidy tables in the contract's schema, for tests, benchmarks and demonstrations.

A simulated 2 x 2 x 2 within-subjects study shaped like the paper's: three unassisted training
runs (the covariates), eight task trials per participant in a Williams-square task order with
alternating mode order, durations with the paper's pattern (hard and wrong slow things down,
aggressive-and-wrong most of all, aggressive-and-right fastest when hard), Likert ratings that
follow the durations, and user-target trajectories at ``rate_hz`` that head first toward the
nearer (wrong) object and then to the farther target. No real participant is involved.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from app.trial.samples import SAMPLE_COLUMNS

TASKS = {  # task -> (difficulty, correctness)
    "easy-right": ("easy", "right"),
    "easy-wrong": ("easy", "wrong"),
    "hard-right": ("hard", "right"),
    "hard-wrong": ("hard", "wrong"),
}
WILLIAMS_4 = ((0, 1, 3, 2), (1, 2, 0, 3), (2, 3, 1, 0), (3, 0, 2, 1))
START = np.array([0.35, 0.0, 0.35])
GOALS = {  # difficulty -> goal names and positions (target last is the farther one)
    "easy": (("bottle", "box"), ((0.55, 0.25, 0.08), (0.45, -0.05, 0.05))),
    "hard": (("bottle", "box"), ((0.68, 0.25, 0.08), (0.45, -0.05, 0.05))),
}
TARGET = "bottle"


def _duration(
    rng: np.random.Generator,
    skill: float,
    dif: str,
    cor: str,
    mode: str,
    practice: int,
    person: float,
) -> float:
    t = 14.0 + 0.3 * (skill - 40.0) + person - 0.6 * practice
    t += 9.0 if dif == "hard" else 0.0
    if mode == "aggressive":
        t += (
            (26.0 + (8.0 if dif == "hard" else 0.0))
            if cor == "wrong"
            else (-10.0 if dif == "hard" else -2.0)
        )
    elif cor == "wrong":
        t += 5.0
    return float(max(6.0, t + rng.normal(0.0, 7.0)))


def _trajectory(rng: np.random.Generator, goals: np.ndarray, n: int, noise: float) -> np.ndarray:
    target, other = goals[0], goals[1]
    via = other + 0.3 * (target - other) + np.array([0.0, 0.0, 0.1])
    s = np.linspace(0.0, 1.0, n)
    a = np.clip(s / 0.45, 0, 1)
    b = np.clip((s - 0.45) / 0.45, 0, 1)
    smooth_a = (3 * a**2 - 2 * a**3)[:, None]
    smooth_b = (3 * b**2 - 2 * b**3)[:, None]
    path = START + smooth_a * (via - START) + smooth_b * (target - via)
    wobble = np.cumsum(rng.normal(0.0, noise / np.sqrt(max(n, 1)) * 3, (n, 3)), axis=0)
    wobble -= np.outer(np.linspace(0, 1, n), wobble[-1])  # end on the target
    return path + wobble


def synthetic_tables(
    n_participants: int = 8,
    *,
    seed: int = 0,
    rate_hz: float = 100.0,
    with_samples: bool = True,
) -> dict[str, pd.DataFrame]:
    """Tables ``trials``, ``samples``, ``ratings``, ``events`` of a simulated study."""
    rng = np.random.default_rng(seed)
    study = _Study(rate_hz=rate_hz, with_samples=with_samples)
    for p in range(n_participants):
        _participant(rng, study, p)
    trials_df = pd.DataFrame(study.trials).drop(columns=["run"])
    samples_df = pd.concat(study.samples, ignore_index=True) if study.samples else pd.DataFrame()
    return {
        "trials": trials_df,
        "samples": samples_df,
        "ratings": pd.DataFrame(study.ratings),
        "events": pd.DataFrame(study.events),
    }


@dataclass
class _Study:
    """The rows written so far (records in the order the tables list them) and the last
    trial id."""

    rate_hz: float
    with_samples: bool
    trials: list[dict[str, Any]] = field(default_factory=list)
    samples: list[pd.DataFrame] = field(default_factory=list)
    ratings: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    trial_id: int = 0

    def next_trial_id(self) -> int:
        self.trial_id += 1
        return self.trial_id


@dataclass(frozen=True)
class _Person:
    pid: str
    session: str
    row: int  # the Williams-square row of the task order
    skill: float
    person: float  # the participant's own offset of every duration


def _participant(rng: np.random.Generator, study: _Study, p: int) -> None:
    """Participant ``p``'s training runs, task runs, answers, covariates and consent."""
    first = len(study.trials)
    who = _Person(
        pid=f"P{p + 1:02d}",
        session=f"S{p + 1:02d}",
        row=p % 4,
        skill=float(rng.normal(40.0, 8.0)),
        person=float(rng.normal(0.0, 5.0)),
    )
    baseline = float(np.clip(np.round(rng.normal(4.0, 1.0) * 3) / 3, 1, 7))
    training = [max(10.0, who.skill + rng.normal(0, 4)) for _ in range(3)]
    for k, d in enumerate(training):
        study.trials.append(_training_trial(study.next_trial_id(), who, k, d))
    task_names = list(TASKS)
    order = [task_names[i] for i in WILLIAMS_4[who.row]]
    first_mode = "timid" if p % 2 == 0 else "aggressive"
    position = 0
    for ti, task in enumerate(order):
        modes = [first_mode, "aggressive" if first_mode == "timid" else "timid"]
        if ti % 2:
            modes.reverse()
        durations = {}
        for run, mode in enumerate(modes):
            position += 1
            durations[mode] = _task_run(rng, study, who, task, mode, position, first=run == 0)
        _answers(rng, study, who, task, modes, durations)
    for rec in study.trials[first:]:
        rec["training_time_s"] = float(np.mean(training))
        rec["baseline_rating"] = baseline
        rec["tasks_completed"] = int(rec["position"]) - 1 if rec["phase"] == "task" else 0
    study.events.append(
        {
            "participant": who.pid,
            "session_id": who.session,
            "at": "2026-11-22T10:00:00Z",
            "kind": "consent",
            "detail": json.dumps({"accepted": True}),
        }
    )


def _training_trial(trial_id: int, who: _Person, k: int, duration: float) -> dict[str, Any]:
    return {
        "participant": who.pid,
        "session_id": who.session,
        "phase": "training",
        "schedule_row": who.row,
        "position": np.nan,
        "task": "training",
        "difficulty": "",
        "correctness": "",
        "mode": "none",
        "attempt": 1,
        "status": "completed",
        "outcome": "success",
        "success": True,
        "duration_s": duration,
        "started_at": f"2026-11-22T10:{k:02d}:00Z",
        "goal_names": json.dumps(["mug"]),
        "goal_positions": json.dumps([[0.5, -0.25, 0.05]]),
        "target": "mug",
        "trial_id": trial_id,
    }


def _task_run(
    rng: np.random.Generator,
    study: _Study,
    who: _Person,
    task: str,
    mode: str,
    position: int,
    *,
    first: bool,
) -> float:
    """One task run at ``position`` (its trial row, and its samples if asked); its duration."""
    dif, cor = TASKS[task]
    trial_id = study.next_trial_id()
    dur = _duration(rng, who.skill, dif, cor, mode, position - 1, who.person)
    names, pos = GOALS[dif]
    study.trials.append(
        {
            "participant": who.pid,
            "session_id": who.session,
            "phase": "task",
            "schedule_row": who.row,
            "position": position,
            "task": task,
            "difficulty": dif,
            "correctness": cor,
            "mode": mode,
            "attempt": 1,
            "status": "completed",
            "outcome": "success",
            "success": True,
            "duration_s": dur,
            "started_at": f"2026-11-22T11:{position:02d}:00Z",
            "goal_names": json.dumps(list(names)),
            "goal_positions": json.dumps([list(x) for x in pos]),
            "target": TARGET,
            "trial_id": trial_id,
            "run": "first" if first else "second",
        }
    )
    if study.with_samples:
        study.samples.append(
            _samples(rng, trial_id, who.pid, np.array(pos), names, dur, study.rate_hz, mode)
        )
    return dur


def _answers(
    rng: np.random.Generator,
    study: _Study,
    who: _Person,
    task: str,
    modes: list[str],
    durations: dict[str, float],
) -> None:
    """The preference between the task's two runs and each run's ratings, which follow the
    durations; written on the two trial rows and as rating rows."""
    gap = durations["timid"] - durations["aggressive"]
    pref = int(np.clip(np.round(gap / 6.0 + rng.normal(0, 0.7)), -3, 3))
    raw = 4 + pref if modes[1] == "aggressive" else 4 - pref
    mean_t = (durations["timid"] + durations["aggressive"]) / 2
    answer = {"participant": who.pid, "session_id": who.session, "phase": "task", "task": task}
    for rec in study.trials[-2:]:
        rec["preference"] = raw
        rec["preference_aggressive"] = pref
        for item, scale in (("helpful", 7.0), ("matched", 8.0), ("teammate", 7.5)):
            v = 4 + (mean_t - rec["duration_s"]) / scale + rng.normal(0, 0.6)
            rec[item] = int(np.clip(np.round(v), 1, 7))
            study.ratings.append(
                {
                    **answer,
                    "mode": rec["mode"],
                    "run": rec["run"],
                    "item": item,
                    "value": rec[item],
                    "answered_at": rec["started_at"],
                }
            )
    study.ratings.append(
        {
            **answer,
            "mode": None,
            "run": None,
            "item": "preference",
            "value": raw,
            "answered_at": study.trials[-1]["started_at"],
        }
    )


def _samples(
    rng: np.random.Generator,
    trial_id: int,
    pid: str,
    goals: np.ndarray,
    names: tuple[str, ...],
    duration: float,
    rate_hz: float,
    mode: str,
) -> pd.DataFrame:
    n = max(2, int(duration * rate_hz))
    xyz = _trajectory(rng, goals, n, 0.03 if mode == "aggressive" else 0.015)
    dist = np.linalg.norm(xyz[:, None, :] - goals[None], axis=2)
    logits = -dist / 0.05
    prob = np.exp(logits - logits.max(axis=1, keepdims=True))
    prob /= prob.sum(axis=1, keepdims=True)
    pred = prob.argmax(axis=1)
    conf = np.clip(1 - dist[np.arange(n), pred] / 0.4, 0, 1)
    alpha = (
        np.where(conf > 0.4, 0.9, 0.0)
        if mode == "aggressive"
        else np.minimum(conf / 0.7, 1.0) * 0.5
    )
    cols: dict[str, object] = {"trial_id": trial_id, "participant": pid, "tick": np.arange(n)}
    for column in SAMPLE_COLUMNS:  # the export's samples columns, zeros unless set below
        if column == "probabilities":
            cols.update({f"prob_{k}": prob[:, k] for k in range(len(names))})
        else:
            cols[column] = np.zeros(n)
    cols.update(
        t=np.arange(n) / rate_hz,
        alpha=alpha,
        confidence=conf,
        predicted=np.array(names)[pred],
        gripper=np.where(np.arange(n) > 0.9 * n, 1.0, 0.0),
        events="",
    )
    for j, axis in enumerate("xyz"):
        cols[f"target_{axis}"] = xyz[:, j]
        cols[f"ee_{axis}"] = xyz[:, j]
    return pd.DataFrame(cols)


__all__ = ["GOALS", "TASKS", "synthetic_tables"]

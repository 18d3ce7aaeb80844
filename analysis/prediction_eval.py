"""Offline evaluation of goal prediction on logged trajectories (section 5.2).

Every logged task trajectory of user targets ``x_0..x_T`` is replayed, tick by tick, through
the same ``app.blending`` predictors the study runs (``reset(x_0)``, then ``update(x_t)``):

- success rate = share of the ticks at which ``argmax_G P(G | xi_{S->x_t})`` is the target;
- time to the first lasting correct prediction = ``t`` (from the trial's first tick) from which
  the prediction stays correct to the end (NaN when the last prediction is wrong).

A goal the robot moved during the trial (its object was nudged: a ``goal_moved`` event in the
samples) moves in the replay at the same tick, so both predictors see the goals the robot saw.

The factorial ANOVA on predictor x difficulty x correctness x mode (OLS, sum-to-zero, type III)
has 128 - 16 = 112 residual df with 8 participants, as in the paper.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from analysis.anova import FactorialAnovaResult, factorial_anova
from analysis.design import require_columns
from analysis.errors import DataError, SchemaError
from analysis.rm_anova import RMAnovaResult, rm_anova
from analysis.timing import design_levels
from app.blending import BlendingError, GoalMoves, predictor_from_config
from app.trial.events import EventKind, TrialEventError, decode_events

PREDICTORS: dict[str, dict[str, Any]] = {
    "amnesic": {"kind": "amnesic", "temperature": 0.05},
    "memory": {"kind": "memory", "cost": "squared_velocity"},
}
"""The paper's two predictors: amnesic (nearest goal) and memory-based with the workspace sum
of squared velocities (eq. 9); configs for ``app.blending.predictor_from_config``."""

DEFAULTS = {"amnesic": {"temperature": 0.05}, "memory": {"cost": "length", "rationality": 1.0}}
"""``app.blending.predictor_from_config``'s defaults for keys a protocol table leaves out."""


@dataclass(frozen=True)
class PredictorChoice:
    """One replayed predictor: its config and where it came from, for the report."""

    name: str
    config: dict[str, Any]
    source: str  # e.g. "the protocol's [prediction.memory]", "the paper's default"

    def describe(self) -> str:
        cfg = {**DEFAULTS.get(str(self.config.get("kind")), {}), **self.config}
        params = ", ".join(
            f"{k} {_fmt_param(v)}" for k, v in cfg.items() if k not in ("kind", "space")
        )
        return f"{self.name}: {params or 'no parameters'} ({self.source})"


def _fmt_param(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def protocol_predictors(
    prediction: Mapping[str, Mapping[str, Any]] | None,
    defaults: Mapping[str, Mapping[str, Any]] = PREDICTORS,
) -> tuple[dict[str, dict[str, Any]], list[PredictorChoice]]:
    """The predictors to replay for a protocol with these [prediction.<name>] tables.

    For each default (amnesic, memory-based) the protocol's first table of the same ``kind`` is
    used as the study ran it (keys it leaves out take app.blending's defaults); if the protocol
    has none, or only one in configuration space (the replay sees workspace targets), the
    paper's default stays. Returns the configs and how each was chosen.
    """
    configs: dict[str, dict[str, Any]] = {}
    chosen: list[PredictorChoice] = []
    tables = {k: dict(v) for k, v in (prediction or {}).items() if isinstance(v, Mapping)}
    for name, default in defaults.items():
        kind = default.get("kind")
        same = [(k, t) for k, t in tables.items() if t.get("kind") == kind]
        usable = [(k, t) for k, t in same if t.get("space", "workspace") == "workspace"]
        if usable:
            key, table = usable[0]
            cfg = {k: v for k, v in table.items() if k != "space"}
            source = f"the protocol's [prediction.{key}]"
        elif same:
            cfg = dict(default)
            source = (
                "the paper's default; the protocol's "
                + ", ".join(f"[prediction.{k}]" for k, _ in same)
                + " predicts in configuration space, which a replay of the logged "
                "workspace targets cannot reproduce"
            )
        else:
            cfg = dict(default)
            source = f"the paper's default; the protocol has no prediction table of kind {kind!r}"
        configs[name] = cfg
        chosen.append(PredictorChoice(name, cfg, source))
    return configs, chosen


TARGET_COLUMNS = ("target_x", "target_y", "target_z")
EVAL_COLUMNS = [
    "trial_id",
    "participant",
    "task",
    "difficulty",
    "correctness",
    "mode",
    "predictor",
    "n_ticks",
    "success_rate",
    "time_to_correct_s",
    "fraction_to_correct",
    "duration_s",
]


@dataclass(frozen=True)
class Replay:
    """Per-tick replay of one trajectory through one predictor."""

    t: np.ndarray  # (T,) seconds from the first tick
    points: np.ndarray  # (T, d) the inputs replayed
    probabilities: np.ndarray  # (T, n_goals)
    predicted: np.ndarray  # (T,) goal index
    correct: np.ndarray | None  # (T,) predicted == target, when the target is known


def make_predictor(config: Mapping[str, Any], points: np.ndarray) -> Any:
    """A predictor from ``app.blending`` built from a plain config table over ``points``."""
    try:
        return predictor_from_config(dict(config), points=points, where="predictor")
    except BlendingError as e:
        raise DataError(f"cannot build the predictor: {e}") from e


def replay(
    points: np.ndarray,
    trajectory: np.ndarray,
    predictor: Any,
    *,
    t: np.ndarray | None = None,
    target: int | None = None,
    moves: GoalMoves | None = None,
) -> Replay:
    """Feed ``trajectory`` (T, d) to ``predictor`` over goals ``points`` (n, d), tick by tick;
    ``moves`` (logged goal moves) are applied before the prediction of their row."""
    traj = np.ascontiguousarray(trajectory, dtype=float)
    if traj.ndim != 2 or traj.shape[0] == 0:
        raise DataError(f"a trajectory must be a non-empty (T, d) array, got shape {traj.shape}")
    if traj.shape[1] != points.shape[1]:
        raise DataError(
            f"trajectory points have {traj.shape[1]} coordinates but the goals "
            f"have {points.shape[1]}; give both in the same space"
        )
    bad = ~np.isfinite(traj).all(axis=1)
    if bad.any():
        raise DataError(
            f"the trajectory has {int(bad.sum())} row(s) with missing or infinite "
            f"coordinates (first at row {int(np.flatnonzero(bad)[0])}); "
            "remove or fill them"
        )
    n_ticks, n_goals = traj.shape[0], points.shape[0]
    probs = np.empty((n_ticks, n_goals))
    pred = np.empty(n_ticks, dtype=int)
    at = moves.by_row() if moves is not None and len(moves) else {}
    current = np.array(points, dtype=float)
    try:
        predictor.reset(traj[0])
        update = predictor.update
        for i in range(n_ticks):
            if i in at:
                for goal, position in at[i]:
                    current[goal] = position
                predictor.set_points(current.copy())
            g = update(traj[i])
            probs[i] = g.probabilities
            pred[i] = g.index
    except BlendingError as e:
        raise DataError(f"the predictor rejected the trajectory: {e}") from e
    tt = np.arange(n_ticks, dtype=float) if t is None else np.asarray(t, dtype=float) - t[0]
    correct = None if target is None else pred == target
    return Replay(t=tt, points=traj, probabilities=probs, predicted=pred, correct=correct)


def first_lasting_correct(correct: np.ndarray) -> int | None:
    """Index from which ``correct`` stays True to the end; None if the last entry is False."""
    if len(correct) == 0 or not correct[-1]:
        return None
    wrong = np.flatnonzero(~correct)
    return int(wrong[-1] + 1) if len(wrong) else 0


def trial_goals(row: Mapping[str, Any]) -> tuple[list[str], np.ndarray, int]:
    """Goal names, positions (n, 3) and the target's index of one trial row."""
    names, positions, target = row.get("goal_names"), row.get("goal_positions"), row.get("target")
    tid = row.get("trial_id")
    if not isinstance(names, list) or not isinstance(positions, list) or len(names) < 1:
        raise SchemaError(
            f"trial {tid}: goal_names/goal_positions must be JSON lists, got "
            f"{names!r} / {positions!r}"
        )
    pts = np.asarray(positions, dtype=float)
    if pts.shape != (len(names), 3):
        raise SchemaError(
            f"trial {tid}: goal_positions must be {len(names)} [x, y, z] "
            f"triples, got shape {pts.shape}"
        )
    if target not in names:
        raise SchemaError(f"trial {tid}: target {target!r} is not among the goals {names}")
    return list(names), pts, names.index(target)


Trajectory = tuple[np.ndarray, np.ndarray, list[tuple[int, Any]]]
"""``(t, user targets, [(row, events), ...] of the rows that move a goal)`` of one trial."""


def trial_trajectories(samples: pd.DataFrame) -> dict[Any, Trajectory]:
    require_columns(samples, ["trial_id", "t", *TARGET_COLUMNS], what="the samples table")
    order = ["trial_id", "tick"] if "tick" in samples.columns else ["trial_id", "t"]
    s = samples.sort_values(order, kind="stable")
    ids = s["trial_id"].to_numpy()
    xyz = s[list(TARGET_COLUMNS)].to_numpy(dtype=float)
    t = s["t"].to_numpy(dtype=float)
    if len(ids) == 0:
        return {}
    moving = np.zeros(len(ids), dtype=bool)
    if "events" in s.columns:  # JSON text (store, CSV) or lists (Parquet): search their text
        moving = (
            s["events"].astype(str).str.contains(EventKind.GOAL_MOVED.value, regex=False).to_numpy()
        )
    events = s["events"].to_numpy() if moving.any() else None
    cuts = np.flatnonzero(ids[1:] != ids[:-1]) + 1
    starts, ends = np.r_[0, cuts], np.r_[cuts, len(ids)]
    out: dict[Any, Trajectory] = {}
    for a, b in zip(starts, ends, strict=True):
        rows = (
            []
            if events is None
            else [(int(i - a), events[i]) for i in np.flatnonzero(moving[a:b]) + a]
        )
        out[ids[a]] = (t[a:b], xyz[a:b], rows)
    return out


def goal_moves(rows: list[tuple[int, Any]], names: Sequence[str], tid: Any) -> GoalMoves | None:
    """The logged goal moves of trial ``tid`` (``None`` when its goals never moved)."""
    if not rows:
        return None
    try:
        moves = [
            (row, event.obj, event.position)
            for row, events in rows
            for event in decode_events(events)
            if event.kind is EventKind.GOAL_MOVED
        ]
        return GoalMoves.from_moves(moves, names)
    except (BlendingError, TrialEventError) as e:
        raise SchemaError(f"trial {tid}: a goal_moved event cannot be read: {e}") from e


def score_trajectory(
    points: np.ndarray,
    t: np.ndarray,
    xyz: np.ndarray,
    target: int,
    predictors: Mapping[str, Mapping[str, Any]],
    moves: GoalMoves | None = None,
) -> list[dict[str, Any]]:
    """Success rate and time to the first lasting correct prediction, per predictor."""
    out = []
    for name, cfg in predictors.items():
        rep = replay(points, xyz, make_predictor(cfg, points), t=t, target=target, moves=moves)
        assert rep.correct is not None
        first = first_lasting_correct(rep.correct)
        span = rep.t[-1] if rep.t[-1] > 0 else np.nan
        out.append(
            {
                "predictor": name,
                "n_ticks": len(t),
                "success_rate": float(rep.correct.mean()),
                "time_to_correct_s": float(rep.t[first]) if first is not None else np.nan,
                "fraction_to_correct": float(rep.t[first] / span) if first is not None else np.nan,
            }
        )
    return out


def _score_job(job: tuple[Any, ...]) -> list[dict[str, Any]]:
    return score_trajectory(*job)


def evaluate_predictions(
    cells: pd.DataFrame,
    samples: pd.DataFrame,
    *,
    predictors: Mapping[str, Mapping[str, Any]] = PREDICTORS,
    workers: int | None = None,
) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """Replay every trial of ``cells`` (task_cells output) that has samples, per predictor.

    Returns one row per trial and predictor (``EVAL_COLUMNS``) and notes (trials without
    samples). ``workers`` > 1 replays trials in that many forked processes (default: up to 2
    when there are more than 50,000 ticks and the caller runs no other threads); the results
    do not depend on it.
    """
    require_columns(
        cells, ["trial_id", "goal_names", "goal_positions", "target"], what="the trials table"
    )
    trajs = trial_trajectories(samples)
    jobs, meta, missing = [], [], []
    for _, row in cells.iterrows():
        tid = row["trial_id"]
        if tid not in trajs:
            missing.append(str(tid))
            continue
        names, pts, target = trial_goals(row)
        t, xyz, moved = trajs[tid]
        jobs.append((pts, t, xyz, target, dict(predictors), goal_moves(moved, names, tid)))
        meta.append(
            {
                "trial_id": tid,
                "participant": row["participant"],
                "task": row["task"],
                "difficulty": row["difficulty"],
                "correctness": row["correctness"],
                "mode": row["mode"],
                "duration_s": row.get("duration_s", np.nan),
            }
        )
    if workers is None:  # forking a threaded process (e.g. a server) is unsafe: stay serial
        ticks = sum(len(j[1]) for j in jobs)
        big = ticks > 50_000 and threading.active_count() == 1
        workers = min(2, os.cpu_count() or 1) if big else 1
    if workers > 1 and len(jobs) > 1:
        ctx = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            scored = list(pool.map(_score_job, jobs, chunksize=max(1, len(jobs) // (4 * workers))))
    else:
        scored = [_score_job(j) for j in jobs]
    rows = [{**m, **r} for m, rs in zip(meta, scored, strict=True) for r in rs]
    notes = []
    if missing:
        notes.append(
            f"{len(missing)} task trial(s) have no samples and were not replayed "
            f"(trial_id {', '.join(missing[:10])}{' ...' if len(missing) > 10 else ''})"
        )
    return pd.DataFrame(rows, columns=EVAL_COLUMNS), tuple(notes)


def prediction_anova(
    evals: pd.DataFrame,
    *,
    dv: str = "success_rate",
    levels: Mapping[str, Sequence[str]] | None = None,
) -> FactorialAnovaResult:
    """Factorial ANOVA of ``dv`` on predictor x difficulty x correctness x mode (type III);
    design factors with a single level in the data are left out of the model."""

    data = evals.copy()
    orders = {"predictor": tuple(dict.fromkeys(evals["predictor"])), **design_levels(evals, levels)}
    factors = [f for f, lv in orders.items() if len(lv) >= 2]
    for f in factors:
        data[f] = pd.Categorical(data[f].astype(str), categories=list(orders[f]))
    return factorial_anova(data, dv=dv, factors=factors)


def prediction_rm_anova(
    evals: pd.DataFrame,
    *,
    dv: str = "success_rate",
    levels: Mapping[str, Sequence[str]] | None = None,
) -> RMAnovaResult:
    """Repeated-measures ANOVA of ``dv`` over participant x condition x predictor: each
    participant's mean per predictor and condition (repeated trials averaged), so a trajectory's
    two replays and a participant's trials are not counted as independent observations;
    participants lacking a cell are dropped (named in the notes)."""

    data = evals.copy()
    orders = {"predictor": tuple(dict.fromkeys(evals["predictor"])), **design_levels(evals, levels)}
    factors = [f for f, lv in orders.items() if len(lv) >= 2]
    for f in factors:
        data[f] = pd.Categorical(data[f].astype(str), categories=list(orders[f]))
    return rm_anova(data, dv=dv, subject="participant", within=factors, drop_incomplete=True)

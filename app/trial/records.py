"""What a trial produces: one ``TickRecord`` per control tick and a ``TrialResult`` at the end."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

OUTCOMES = ("success", "wrong_object", "dropped", "pushed_off", "timeout", "aborted", "interrupted")


@dataclass(frozen=True, slots=True)
class TickRecord:
    """One control tick, after physics.

    ``t``: simulated time (s, pauses excluded); ``q``: robot configuration Q after the tick;
    ``u``: the user's next configuration U; ``p``: the policy's P; ``command``:
    ``(1 - alpha) U + alpha P`` sent to the servos; ``probabilities``: ``P(G | xi)``;
    ``predicted``: index of G*; ``user_target``: the clamped target (3,); ``ee``: TCP (3,);
    ``gripper``: finger opening (m); ``events``: what happened this tick;
    ``motion_agreement``: cosine of the user's motion and the robot's heading (Fig. 15);
    ``rationality``: the user's estimated rationality toward G* (1/m). Both from
    ``app.blending.BlendRecord`` while reaching (0 and NaN otherwise).
    """

    tick: int
    t: float
    q: np.ndarray
    u: np.ndarray
    p: np.ndarray
    command: np.ndarray
    alpha: float
    confidence: float
    probabilities: np.ndarray
    predicted: int
    user_target: np.ndarray
    ee: np.ndarray
    gripper: float
    events: tuple[str, ...] = ()
    motion_agreement: float = 0.0
    rationality: float = float("nan")

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (lists for arrays)."""
        return {
            name: (value.tolist() if isinstance(value, np.ndarray) else value)
            for name, value in ((n, getattr(self, n)) for n in self.__slots__)
        }


@dataclass(frozen=True)
class TrialResult:
    """How a trial ended. ``duration_s`` is simulated time, which excludes pauses."""

    outcome: str
    success: bool
    duration_s: float
    ticks: int
    records: tuple[TickRecord, ...]
    goal_names: tuple[str, ...]
    target: str
    seed: int
    task: str = ""
    mode: str = ""
    events: tuple[tuple[float, str], ...] = field(default=())

    def summary(self) -> dict[str, Any]:
        """The one-line JSON summary the CLI prints."""
        return {
            "task": self.task,
            "mode": self.mode,
            "seed": self.seed,
            "outcome": self.outcome,
            "success": self.success,
            "duration_s": round(self.duration_s, 4),
            "ticks": self.ticks,
            "target": self.target,
            "events": len(self.events),
        }


def save_records(result: TrialResult, path: str | Path) -> Path:
    """Write a trial's records to ``path`` (``.npz``): arrays per field plus a JSON summary."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    recs = result.records
    arrays: dict[str, np.ndarray] = {
        "tick": np.array([r.tick for r in recs], dtype=np.int64),
        "t": np.array([r.t for r in recs]),
        "alpha": np.array([r.alpha for r in recs]),
        "confidence": np.array([r.confidence for r in recs]),
        "predicted": np.array([r.predicted for r in recs], dtype=np.int64),
        "gripper": np.array([r.gripper for r in recs]),
        "motion_agreement": np.array([r.motion_agreement for r in recs]),
        "rationality": np.array([r.rationality for r in recs]),
    }
    for name in ("q", "u", "p", "command", "probabilities", "user_target", "ee"):
        arrays[name] = np.array([getattr(r, name) for r in recs]).reshape(len(recs), -1)
    meta = {
        **result.summary(),
        "goal_names": list(result.goal_names),
        "events": [[t, e] for t, e in result.events],
        "tick_events": [list(r.events) for r in recs],
    }
    np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def load_records(path: str | Path) -> tuple[dict[str, Any], tuple[TickRecord, ...]]:
    """Read what ``save_records`` wrote: ``(summary, records)``."""
    with np.load(Path(path), allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        cols = {k: z[k] for k in z.files if k != "meta"}
    new = "rationality" in cols  # files saved before these columns existed lack them
    records = tuple(
        TickRecord(
            tick=int(cols["tick"][i]),
            t=float(cols["t"][i]),
            q=cols["q"][i],
            u=cols["u"][i],
            p=cols["p"][i],
            command=cols["command"][i],
            alpha=float(cols["alpha"][i]),
            confidence=float(cols["confidence"][i]),
            probabilities=cols["probabilities"][i],
            predicted=int(cols["predicted"][i]),
            user_target=cols["user_target"][i],
            ee=cols["ee"][i],
            gripper=float(cols["gripper"][i]),
            events=tuple(meta["tick_events"][i]),
            motion_agreement=float(cols["motion_agreement"][i]) if new else 0.0,
            rationality=float(cols["rationality"][i]) if new else math.nan,
        )
        for i in range(len(cols["t"]))
    )
    return meta, records


def records_from_samples(samples: Any) -> tuple[TickRecord, ...]:
    """Tick records from a study store's ``samples`` rows of one trial (a pandas DataFrame with
    ``tick, t, q1..q7, u1.., p1.., cmd1.., alpha, confidence, predicted, probabilities,
    target_x.., ee_x.., gripper, events``, optionally ``motion_agreement, rationality``;
    ``probabilities`` and ``events`` as JSON text)."""
    cols = samples.columns

    def block(prefix: str, names: Sequence[str]) -> np.ndarray:
        missing = [n for n in names if n not in cols]
        if missing:
            raise ValueError(f"samples: missing column(s) {missing}")
        return samples[list(names)].to_numpy(dtype=float)

    q = block("q", [f"q{i}" for i in range(1, 8)])
    u = block("u", [f"u{i}" for i in range(1, 8)])
    p = block("p", [f"p{i}" for i in range(1, 8)])
    cmd = block("cmd", [f"cmd{i}" for i in range(1, 8)])
    target = block("target", ["target_x", "target_y", "target_z"])
    ee = block("ee", ["ee_x", "ee_y", "ee_z"])
    out = []
    for i, row in enumerate(samples.itertuples(index=False)):
        probs = row.probabilities
        events = row.events
        out.append(
            TickRecord(
                tick=int(row.tick),
                t=float(row.t),
                q=q[i],
                u=u[i],
                p=p[i],
                command=cmd[i],
                alpha=float(row.alpha),
                confidence=float(row.confidence),
                probabilities=np.array(json.loads(probs) if isinstance(probs, str) else probs),
                predicted=int(row.predicted),
                user_target=target[i],
                ee=ee[i],
                gripper=float(row.gripper),
                events=tuple(json.loads(events) if isinstance(events, str) else events),
                motion_agreement=_number(getattr(row, "motion_agreement", None), 0.0),
                rationality=_number(getattr(row, "rationality", None), math.nan),
            )
        )
    return tuple(out)


def _number(value: Any, empty: float) -> float:
    """A stored number, ``empty`` for a missing or NULL one."""
    return empty if value is None or value != value else float(value)

"""What a trial produces: one ``TickRecord`` per control tick and a ``TrialResult`` at the end."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from app.trial.events import TrialEvent, decode, encode

OUTCOMES = ("success", "wrong_object", "dropped", "pushed_off", "timeout", "aborted", "interrupted")


@dataclass(frozen=True, slots=True)
class TickRecord:
    """One control tick, after physics.

    ``t``: simulated time (s, pauses excluded); ``q``: robot configuration Q after the tick;
    ``u``: the user's next configuration U; ``p``: the policy's P; ``command``:
    ``(1 - alpha) U + alpha P`` sent to the servos; ``probabilities``: ``P(G | xi)``;
    ``predicted``: index of G*; ``user_target``: the clamped target (3,); ``ee``: TCP (3,);
    ``gripper``: finger opening (m); ``events``: what happened this tick (``app.trial.events``).
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
    events: tuple[TrialEvent, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (lists for arrays, events as their stored text)."""
        out = {
            name: (value.tolist() if isinstance(value, np.ndarray) else value)
            for name, value in ((n, getattr(self, n)) for n in self.__slots__)
        }
        out["events"] = [encode(e) for e in self.events]
        return out


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
    events: tuple[tuple[float, TrialEvent], ...] = field(default=())

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
    }
    for name in ("q", "u", "p", "command", "probabilities", "user_target", "ee"):
        arrays[name] = np.array([getattr(r, name) for r in recs]).reshape(len(recs), -1)
    meta = {
        **result.summary(),
        "goal_names": list(result.goal_names),
        "events": [[t, encode(e)] for t, e in result.events],
        "tick_events": [[encode(e) for e in r.events] for r in recs],
    }
    np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def load_records(path: str | Path) -> tuple[dict[str, Any], tuple[TickRecord, ...]]:
    """Read what ``save_records`` wrote: ``(summary, records)`` (the summary's ``events`` stay
    ``[t, text]`` pairs; ``app.trial.events.decode`` reads a text)."""
    with np.load(Path(path), allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        cols = {k: z[k] for k in z.files if k != "meta"}
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
            events=tuple(decode(e) for e in meta["tick_events"][i]),
        )
        for i in range(len(cols["t"]))
    )
    return meta, records

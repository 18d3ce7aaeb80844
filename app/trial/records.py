"""What a trial produces: one ``TickRecord`` per control tick and a ``TrialResult`` at the end
(files of them: ``app.trial.record_file``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from app.frozen import quick_init
from app.trial.events import EventKind, TrialEvent, encode

OUTCOMES = (
    "success",
    "wrong_object",
    "dropped",
    "knocked_over",
    "pushed_off",
    "timeout",
    "aborted",
    "interrupted",
)
"""How a trial can end: ``success`` (the target lifted), ``wrong_object`` (the other object
lifted), ``dropped`` (a held object fell out of the gripper or would not come up),
``knocked_over`` (an object was knocked over, never grasped) and ``pushed_off`` (an object fell
off the table) -- these two only under ``on_knock = "end"``, and ``dropped`` too: under
``"reset"`` the run goes on --, ``timeout``, ``aborted`` (the experimenter) and
``interrupted`` (the participant was lost)."""


class BlendTick(NamedTuple):
    """What a trial keeps of the blender's last tick (``app.blending.BlendRecord``): what the
    input sources see (``alpha``, ``predicted``) and the tick records carry. ``alpha`` as
    applied (0 while the robot holds back for a lying goal); ``probabilities``: ``P(G | xi)``;
    ``predicted``: index of G* (-1 before the first blend). Named and immutable, and as cheap
    per tick as the plain tuple it replaces (a ``NamedTuple``: the control tick makes one)."""

    alpha: float
    confidence: float
    probabilities: np.ndarray
    predicted: int
    motion_agreement: float = 0.0
    rationality: float = math.nan


@quick_init
@dataclass(frozen=True, slots=True)
class TickRecord:
    """One control tick, after physics.

        ``t``: simulated time (s, pauses excluded); ``q``: robot configuration Q after the tick;
        ``u``: the user's next configuration U; ``p``: the policy's P; ``command``:
        ``(1 - alpha) U + alpha P`` sent to the servos; ``probabilities``: ``P(G | xi)``;
        ``predicted``: index of G*; ``user_target``: the user's input position the prediction read
    (3,, clamped: the target, or under a relative mapping the path their own input traced);
    ``ee``: TCP (3,);
        ``gripper``: finger opening (m); ``events``: what happened this tick (``app.trial.events``);
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
    events: tuple[TrialEvent, ...] = ()
    motion_agreement: float = 0.0
    rationality: float = float("nan")

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
            "knocks": self.count(EventKind.KNOCKED_OVER),
            "pushed_off": self.count(EventKind.PUSHED_OFF),
            "drops": self.count(EventKind.DROPPED),
        }

    def count(self, kind: EventKind) -> int:
        """How many events of ``kind`` the trial logged (e.g. its knocks)."""
        return sum(1 for _, e in self.events if e.kind is kind)

"""Session helpers shared by the session, questionnaire and event tests: enrol a participant
with a stub trial factory, walk a session to a step, answer its questions, and the simulated
participant's lived runs and screens."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from app.trial import TickRecord
from study.protocol import (
    AttentionItem,
    ChoiceItem,
    LikertItem,
    NumberItem,
    Protocol,
    RetentionItem,
)
from study.session import Session
from study.store import (
    Store,
)

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL_PATH = ROOT / "protocols" / "dragan2013.toml"


class StubTrial:
    """Stand-in for ``app.trial.Trial``: ``ticks`` control ticks, then ``outcome``."""

    def __init__(self, config: Any, input_source: Any, seed: int, *, ticks: int = 5) -> None:
        self.config = config
        self.seed = seed
        self.n = ticks
        self.ticks = 0
        self.outcome: str | None = None
        self._paused = False
        self.goal_count = len(config.scene.object_names)

    @property
    def t(self) -> float:
        return self.ticks * self.config.dt

    @property
    def done(self) -> bool:
        return self.outcome is not None

    @property
    def success(self) -> bool:
        return self.outcome == "success"

    def pause(self) -> None:
        self._paused = True

    def resume(self) -> None:
        self._paused = False

    def abort(self, outcome: str = "aborted") -> None:
        if self.outcome is None:
            self.outcome = outcome

    def tick(self) -> TickRecord | None:
        if self._paused or self.done:
            return None
        self.ticks += 1
        if self.ticks >= self.n:
            self.outcome = "success"
        v = np.full(7, 0.01 * self.ticks)
        k = self.goal_count
        return TickRecord(
            tick=self.ticks - 1,
            t=self.t,
            q=v,
            u=v,
            p=v,
            command=v,
            alpha=0.1,
            confidence=0.2,
            probabilities=np.full(k, 1.0 / k),
            predicted=0,
            user_target=np.zeros(3),
            ee=np.zeros(3),
            gripper=0.04,
        )


def stub_factory(config: Any, input_source: Any, seed: int) -> StubTrial:
    return StubTrial(config, input_source, seed)


def enrol(store: Store, protocol: Protocol, participant: str = "P01", **kw: Any) -> Session:
    return Session.enrol(store, protocol, participant, trial_factory=stub_factory, **kw)


def finish_run(session: Session) -> None:
    run = session.start_trial(input_source=None)
    assert run.run_to_end() is not None


def valid_answers(items: Any, *, likert: int = 4) -> dict[str, object]:
    """An acceptable answer to each item: ``likert`` on a rating scale, the correct or the
    keep option of an attention or retention item, the first option of a choice, a number's
    minimum, a short text."""
    out: dict[str, object] = {}
    for item in items:
        if isinstance(item, LikertItem):
            out[item.id] = likert
        elif isinstance(item, AttentionItem):
            out[item.id] = item.correct
        elif isinstance(item, RetentionItem):
            out[item.id] = item.keep
        elif isinstance(item, ChoiceItem):
            out[item.id] = item.options[0]
        elif isinstance(item, NumberItem):
            out[item.id] = item.minimum
        else:
            out[item.id] = "fine"
    return out


def to_step(session: Session, phase: str, *, questionnaire: str | None = None) -> None:
    """Act as a participant until the screen shows ``phase`` (and ``questionnaire``)."""
    for _ in range(200):
        screen = session.screen()
        if screen.phase == phase and (
            questionnaire is None or screen.questionnaire == questionnaire
        ):
            return
        if screen.phase == "waiting":
            session.start()
        elif screen.phase == "consent":
            session.agree()
        elif screen.phase == "ready":
            finish_run(session)
        elif screen.phase == "questions":
            session.answer(valid_answers(screen.items))
        elif screen.phase == "debrief":
            session.finish()
        else:
            raise AssertionError(f"stuck at {screen}")
    raise AssertionError(f"never reached {phase}")

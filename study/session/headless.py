"""Drive a whole session without a browser: the loop shared by ``python -m study run`` and
simulated participants.

``run_headless`` reads ``session.screen()`` and acts as a participant would: agree, start each
trial with an input source from ``input_factory`` and tick it to its end as fast as possible
(or paced to wall-clock time), answer items with ``answerer``, finish. The experimenter's
``start`` is given once at the beginning.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from app.teleop import ScriptedInput
from app.trial import TrialConfig
from study.session.participant_actions import trial_seed
from study.session.screen import Screen
from study.session.session import Session
from study.session.trial_run import TrialRun, TrialSummary


class Answerer(Protocol):
    def observe(self, summary: TrialSummary | None, *, time_limit_s: float) -> None: ...

    def answer(self, screen: Screen) -> Mapping[str, object]: ...


InputFactory = Callable[[TrialConfig, int], Any]
"""``(config, seed) -> input source`` for one trial attempt."""


@dataclass(frozen=True)
class HeadlessReport:
    """What a headless run did (the CLI prints it as its last line)."""

    participant: str
    trials_completed: int
    ratings: int
    status: str

    def as_dict(self) -> dict[str, Any]:
        return {
            "participant": self.participant,
            "trials_completed": self.trials_completed,
            "ratings": self.ratings,
            "status": self.status,
        }


def scripted_input(config: TrialConfig, seed: int) -> ScriptedInput:
    """``app.teleop.ScriptedInput`` seeded for this attempt (moves straight to the target)."""
    return ScriptedInput(seed=seed)


def run_headless(
    session: Session,
    *,
    answerer: Answerer,
    input_factory: InputFactory = scripted_input,
    realtime: bool = False,
    on_trial: Callable[[TrialSummary | None], None] | None = None,
    idle_s: float = 0.01,
) -> HeadlessReport:
    """Run ``session`` from its current step to the end; returns the report."""
    while True:
        screen = session.screen()
        if screen.phase == "done":
            break
        if screen.paused:
            time.sleep(idle_s)
            continue
        if screen.phase == "waiting":
            session.start()
        elif screen.phase == "consent":
            session.agree()
        elif screen.phase == "ready":
            config = session.trial_config()
            attempt = session.overview().attempt or 1
            seed = trial_seed(session.seed + 1, session.cursor, attempt)
            run = session.start_trial(input_source=input_factory(config, seed))
            summary = _drive(run, realtime=realtime, idle_s=idle_s)
            answerer.observe(summary, time_limit_s=config.time_limit_s)
            if on_trial is not None:
                on_trial(summary)
        elif screen.phase == "questions":
            session.answer(answerer.answer(screen))
        elif screen.phase == "debrief":
            session.finish()
        else:  # "running": a run started elsewhere; wait for it
            time.sleep(idle_s)
    return report(session)


def report(session: Session) -> HeadlessReport:
    trials = session.store.trials(session_id=session.session_id)
    return HeadlessReport(
        participant=session.participant,
        trials_completed=sum(t.status == "completed" for t in trials),
        ratings=len(session.store.ratings(session_id=session.session_id)),
        status=session.status,
    )


def _drive(run: TrialRun, *, realtime: bool, idle_s: float) -> TrialSummary | None:
    if not realtime:
        return run.run_to_end(idle_s=idle_s)
    dt = run.config.dt
    start = time.perf_counter()
    while not run.over:
        if run.tick() is None:
            time.sleep(idle_s)
            start += idle_s
            continue
        delay = start + run.ticks * dt - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    return run.summary

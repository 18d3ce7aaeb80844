"""What the experimenter's console shows of one live session: its row in the sessions list
(``session_summary``) and the selected session's detail (``session_detail``): the schedule,
the current condition, the actions its state allows, live plots of the running trial
(``LivePlots``), the timeline of runs and events (``timeline``), a held fault and the attempts
so far. Session time counts from the session's first start, read from the store.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np

from app.trial import TickRecord
from study.protocol import Protocol
from study.server.console_model import SessionDetail, SessionSummary
from study.server.live.timeline import task_text, timeline
from study.session import Overview, Session, TrialRun
from study.session.plan import Plan, build_plan, run_progress
from study.store import Store

LOGGER = logging.getLogger("study.server.live")

FINISHED_NOTE = "no longer live: shown from the store (`python -m study export` writes it out)"
"""Said of a finished session the server has let go (``finished_detail``)."""

PLOT_WINDOW = 1500
"""Ticks kept for the console's live plots (15 s at 100 Hz)."""


class LivePlots:
    """The last ``PLOT_WINDOW`` ticks' arbitration, confidence and goal probabilities.

    The control thread appends (``add``); the console thread reads (``arrays``)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rows: deque[tuple[float, float, float, np.ndarray]] = deque(maxlen=PLOT_WINDOW)
        self.goal_names: tuple[str, ...] = ()

    def restart(self, goal_names: Sequence[str]) -> None:
        """A new run: its goals, no rows."""
        with self._lock:
            self.goal_names = tuple(goal_names)
            self._rows.clear()

    def add(self, record: TickRecord) -> None:
        row = (
            float(record.t),
            float(record.alpha),
            float(record.confidence),
            np.asarray(record.probabilities, float),
        )
        with self._lock:
            self._rows.append(row)

    def arrays(
        self,
    ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(goal names, t, alpha, confidence, probabilities (n, goals))`` read at one moment
        (a run starting in between cannot pair one run's goals with another's rows); empty
        when the rows do not all have the current goals."""
        with self._lock:
            rows = list(self._rows)
            names = self.goal_names
        n = len(names)
        if rows and all(len(r[3]) == n for r in rows):
            return (
                names,
                np.array([r[0] for r in rows]),
                np.array([r[1] for r in rows]),
                np.array([r[2] for r in rows]),
                np.stack([r[3] for r in rows]),
            )
        return names, np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, n))


@dataclass(frozen=True)
class LiveFacts:
    """What the live session knows that the session engine does not."""

    code: str
    connected: bool
    started_at: datetime | None
    """When the session was first started (``None``: not yet)."""
    run: TrialRun | None
    log: tuple[str, ...]
    fault: str | None
    recruitment: tuple[tuple[str, str], ...] = field(default_factory=tuple)
    ended_at: datetime | None = None
    """When the session was over (``None``: not yet): its session time stops there."""


def session_summary(session: Session, facts: LiveFacts) -> SessionSummary:
    return _summary(session.overview(), session.participant, facts)


def _summary(o: Overview, participant: str, facts: LiveFacts) -> SessionSummary:
    return SessionSummary(
        code=facts.code,
        participant=participant,
        state=o.status
        + (" / paused" if o.paused else "")
        + (f" / {o.phase}" if o.phase != o.status else ""),
        position=f"{min(o.step + 1, o.steps)}/{o.steps}",
        connected=facts.connected,
        elapsed_s=None
        if facts.started_at is None
        else ((facts.ended_at or datetime.now(UTC)) - facts.started_at).total_seconds(),
        source="link" if facts.recruitment else "",
    )


def session_detail(session: Session, facts: LiveFacts, plots: LivePlots) -> SessionDetail:
    o = session.overview()
    schedule = _schedule(session.plan)
    condition = condition_line(o)
    goal_names, t, alpha, conf, probs = plots.arrays()
    run = facts.run
    rows, tally = _timeline(session.store, session.session_id)
    return SessionDetail(
        summary=_summary(o, session.participant, facts),
        schedule=schedule,
        cursor=o.step,
        condition=condition,
        trial_elapsed_s=float(run.duration_s()) if run is not None else 0.0,
        paused=o.paused,
        t=t,
        alpha=alpha,
        confidence=conf,
        probabilities=probs,
        goal_names=goal_names,
        log=facts.log,
        fault=facts.fault or _text(session.samples_error),
        trials=_trial_rows(session.store, session.participant),
        actions=o.experimenter_actions,
        timeline=rows,
        tally=tally,
        recruitment=facts.recruitment,
    )


def finished_detail(
    store: Store,
    protocol: Protocol,
    summary: SessionSummary,
    *,
    recruitment: tuple[tuple[str, str], ...] = (),
) -> SessionDetail:
    """The detail of a finished session that is no longer live (``summary``: its last row),
    read from the store: its schedule, attempts and timeline; no actions, no plots."""
    record = store.session(summary.participant)
    plan = build_plan(protocol, tuple(store.assignments(summary.participant)))
    rows, tally = _timeline(store, record.session_id)
    return SessionDetail(
        summary=summary,
        schedule=_schedule(plan),
        cursor=record.cursor,
        condition=f"none: the session is {record.status}; {FINISHED_NOTE}",
        trial_elapsed_s=0.0,
        paused=False,
        trials=_trial_rows(store, summary.participant),
        timeline=rows,
        tally=tally,
        recruitment=recruitment,
    )


def _schedule(plan: Plan) -> list[tuple[str, str, str]]:
    """The console's schedule rows: (step label, task, mode); a trial's label says what the
    participant's page calls it ("Run 1 of 8"), to match what they say to the experimenter."""
    return [
        (
            f"{s.kind} ({s.phase})"
            + (f' #{s.trial_number} ("{run_progress(plan, s).text}")' if s.trial_number else ""),
            s.task or "-",
            (s.mode or "-") + (f", {s.run} run" if s.run else ""),
        )
        for s in plan.steps
    ]


def condition_line(o: Overview) -> str:
    """The current step's condition in one line ("attempt" only where a run is next or on)."""
    attempt = f", attempt {o.attempt}" if o.attempt is not None else ""
    if o.phase == "done":
        return f"none: the session is {o.status}"
    if o.task:
        where = "questions after" if o.step_kind == "questions" else o.training_or_task
        group = f" [{o.group}]" if o.group else ""
        return f"{where}: {task_text(o)}, mode {o.mode}, {o.run} run{attempt}{group}"
    if o.step_kind == "trial":
        return f"practice, unassisted{attempt}"
    if o.step_kind == "questions":
        return f"questions ({o.training_or_task})"
    return o.step_kind or o.phase


def _timeline(store: Store, session_id: int) -> tuple[tuple[tuple[str, str, str], ...], str]:
    try:
        events = store.events(session_id=session_id)
        trials = store.trials(session_id=session_id)
    except Exception:
        LOGGER.debug("could not read the session's timeline", exc_info=True)
        return (), ""
    return timeline(events, trials)


def _trial_rows(store: Store, participant: str) -> tuple[tuple[str, int, str, str, str], ...]:
    """The console's list of attempts, from the store (runs of earlier processes too)."""
    try:
        records = store.trials(participant=participant)
    except Exception:
        LOGGER.debug("could not read the trials for the console", exc_info=True)
        return ()
    return tuple(
        (
            f"{r.trial_number}. {r.phase}" + (f": {r.task}, {r.mode}" if r.task else ""),
            int(r.attempt),
            str(r.status),
            str(r.outcome or "-"),
            "-" if r.duration_s is None else f"{r.duration_s:.1f} s",
        )
        for r in records
    )


def _text(error: BaseException | None) -> str | None:
    return None if error is None else f"{type(error).__name__}: {error}"[:300]

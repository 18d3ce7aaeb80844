"""``TrialRun``: one attempt of a trial step, ticked by the control loop.

The session creates it (``Session.start_trial``). One thread - the control loop, or the
headless loop - calls ``tick()`` repeatedly; each tick advances the ``app.trial`` trial by one
control period and hands its ``TickRecord`` to the session's ``SampleWriter``. When the trial
ends by itself the run reports to the session, which commits the trial and moves on. Pause,
abort (redo, skip, withdraw, end) come from other threads through the session; a lock keeps them
from interleaving with a tick. Whether the run is paused is not the run's to keep: it asks the
session's ``RunState`` (``is_paused``) and follows it down to its trial (``follow_pause``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from app.trial import TrialConfig
from study.session.errors import SessionStateError
from study.session.sample_writer import SampleWriter, sample_row


class TrialLike(Protocol):
    """What the session needs of ``app.trial.Trial``."""

    @property
    def done(self) -> bool: ...

    @property
    def outcome(self) -> str | None: ...

    def tick(self) -> Any | None: ...

    def pause(self) -> None: ...

    def abort(self, outcome: str = "aborted") -> None: ...

    def resume(self) -> None: ...


TrialFactory = Callable[[TrialConfig, Any, int], TrialLike]
"""``(config, input_source, seed) -> trial``; default: ``app.trial.Trial``."""


@dataclass(frozen=True)
class TrialSummary:
    """How an attempt ended: ``duration_s`` excludes pauses; ``ticks`` = samples recorded."""

    trial_id: int
    outcome: str
    success: bool
    duration_s: float
    ticks: int


class TrialRun:
    """One running trial attempt (see module docstring).

    Thread-safety: ``tick`` and ``run_to_end`` from one thread only (enforced); the read-only
    properties from any thread.
    """

    def __init__(
        self,
        *,
        trial: TrialLike,
        trial_id: int,
        step: int,
        attempt: int,
        seed: int,
        config: TrialConfig,
        writer: SampleWriter,
        on_finished: Callable[[TrialRun], None],
        is_paused: Callable[[], bool],
    ) -> None:
        self.trial = trial
        self.trial_id = trial_id
        self.step = step
        self.attempt = attempt
        self.seed = seed
        self.config = config
        self._writer = writer
        self._on_finished = on_finished
        self._is_paused = is_paused
        self._lock = threading.Lock()
        self._ticker: int | None = None
        self._ticks = 0
        self._last_t = 0.0
        self._over = False
        self.summary: TrialSummary | None = None

    # ---- control thread ---------------------------------------------------------------------
    def tick(self) -> Any | None:
        """Advance the trial one control period; returns its ``TickRecord``, or ``None`` while
        paused or once the run is over."""
        me = threading.get_ident()
        if self._ticker is None:
            self._ticker = me
        elif self._ticker != me:
            raise SessionStateError(
                f"trial {self.trial_id} is ticked from a second thread; only the control loop "
                "that started ticking it may call tick()"
            )
        with self._lock:
            if self._over or self._is_paused():
                return None
            record = self.trial.tick()
            if record is not None:
                row = sample_row(self.trial_id, self._ticks, record)
                self._ticks += 1
                self._last_t = float(record.t)
                # may raise StoreError (the store refused earlier batches) with the row queued:
                # the tick is counted, so a retry never writes the same tick number twice
                self._writer.add_row(row)
            finished = bool(self.trial.done)
        if finished:
            self._on_finished(self)
        return record

    def run_to_end(self, *, idle_s: float = 0.01) -> TrialSummary | None:
        """Tick until the run is over (headless driving); waits while paused. Returns the
        summary, or ``None`` if the run was aborted (redo, skip, withdraw, end)."""
        while not self.over:
            if self.tick() is None and not self.over:
                time.sleep(idle_s)
        return self.summary

    # ---- state -----------------------------------------------------------------------------------
    @property
    def over(self) -> bool:
        return self._over

    @property
    def paused(self) -> bool:
        """The session is paused (asked of its ``RunState``)."""
        return self._is_paused()

    @property
    def ticks(self) -> int:
        return self._ticks

    def duration_s(self) -> float:
        """Trial time so far (pauses excluded): the trial's own clock."""
        value = getattr(self.trial, "t", None)
        return float(value) if value is not None else self._last_t

    # ---- called by the session (under its lock) -----------------------------------------------------
    def follow_pause(self) -> None:
        """Pause or resume the trial's clock as the session's state says (no-op once over)."""
        with self._lock:
            if not self._over:
                if self._is_paused():
                    self.trial.pause()
                else:
                    self.trial.resume()

    def end(self, summary: TrialSummary | None) -> None:
        """Mark the run over (no further ticks); ``summary`` None for an aborted run, whose
        trial is told to stop (outcome ``aborted``)."""
        with self._lock:
            if summary is None and not self.trial.done:
                self.trial.abort("aborted")
            self._over = True
            self.summary = summary

"""A thread that calls a function at a fixed rate, paced on the monotonic clock.

Deadlines are absolute: tick ``k`` is due at ``t0 + k / rate_hz``, so sleep jitter does not
accumulate into drift, and a late tick is followed by the next ones without sleeping until the
schedule is met again (simulated time keeps up with the wall clock). Only a stall longer than
``max_lag`` periods (250 ms at 100 Hz) resynchronises: those ticks are counted in ``overruns``
and dropped, never run in a burst. While ``paused`` the
function is not called and the schedule restarts on resume.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from study.errors import StudyError

LOGGER = logging.getLogger("study.server.loop")


class LoopError(StudyError, RuntimeError):
    """The loop was misconfigured (e.g. a non-positive rate)."""


class PacedLoop:
    """Run ``step()`` at ``rate_hz`` in a daemon thread until it returns False or ``stop()``."""

    def __init__(
        self,
        step: Callable[[], bool | None],
        *,
        rate_hz: float,
        name: str = "paced-loop",
        max_lag: float = 25.0,
        history: int = 2048,
        on_start: Callable[[], None] | None = None,
    ) -> None:
        if not rate_hz > 0:
            raise LoopError(f"rate_hz must be positive, got {rate_hz!r}")
        self.step = step
        self.rate_hz = float(rate_hz)
        self.period = 1.0 / self.rate_hz
        self.name = name
        self.max_lag = max_lag
        self.on_start = on_start
        """Called first in the loop's own thread (e.g. to take a scheduling class)."""
        self.ticks = 0
        self.overruns = 0
        self.error: BaseException | None = None
        self._stamps: deque[float] = deque(maxlen=history)
        self._stop = threading.Event()
        self._running = threading.Event()
        self._running.set()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> PacedLoop:
        self._thread.start()
        return self

    def stop(self, *, timeout: float = 2.0) -> None:
        self._stop.set()
        self._running.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    @property
    def paused(self) -> bool:
        return not self._running.is_set()

    def pause(self) -> None:
        self._running.clear()

    def resume(self) -> None:
        self._running.set()

    # -- measurement -----------------------------------------------------------------------
    def achieved_hz(self, *, window_s: float = 2.0) -> float:
        """Ticks per second over the last ``window_s`` seconds of ticking (0 if too few)."""
        stamps = list(self._stamps)
        if len(stamps) < 3:
            return 0.0
        recent = [t for t in stamps if t >= stamps[-1] - window_s]
        if len(recent) < 3:
            return 0.0
        return (len(recent) - 1) / (recent[-1] - recent[0])

    def periods(self) -> np.ndarray:
        """Intervals between consecutive ticks in the history, in seconds."""
        return np.diff(np.asarray(self._stamps))

    # -- the loop --------------------------------------------------------------------------
    def _run(self) -> None:
        if self.on_start is not None:
            self.on_start()
        next_due = time.monotonic()
        while not self._stop.is_set():
            if not self._running.is_set():
                self._running.wait()
                next_due = time.monotonic()
                self._stamps.clear()
                continue
            now = time.monotonic()
            if now < next_due:
                time.sleep(next_due - now)
            now = time.monotonic()
            if now - next_due > self.max_lag * self.period:
                missed = int((now - next_due) / self.period)
                self.overruns += missed
                next_due = now
            self._stamps.append(now)
            try:
                keep_going = self.step()
            except BaseException as exc:  # keep the server up; the owner reads .error
                LOGGER.exception("%s: step failed", self.name)
                self.error = exc
                return
            self.ticks += 1
            if keep_going is False:
                return
            next_due += self.period

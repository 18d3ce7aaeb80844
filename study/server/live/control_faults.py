"""``ControlFaults``: an exception in a control tick, held until the experimenter resumes.

A tick that raises (a full disk included) must never kill the control loop silently: the fault
is kept here (``fault``, shown to the experimenter and making the page ask the participant to
wait), logged to the server log and recorded as a ``control_fault`` event. If the store refused
that event too, it is kept and written, marked ``recorded_late``, when the experimenter resumes
(``clear``). While a fault is held the control loop does not tick.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from study.session import TrialRun

LOGGER = logging.getLogger("study.server.live")

RecordEvent = Callable[[str, Mapping[str, Any]], bool]
"""``(kind, detail) -> written``: the live session's event log (False: the store refused)."""


class ControlFaults:
    """The last control-loop error of one live session (see module docstring)."""

    def __init__(self, *, code: str, record: RecordEvent) -> None:
        self.code = code
        self._record = record
        self.fault: str | None = None
        """The last control-loop error, shown to the experimenter until they resume."""
        self._unrecorded: dict[str, Any] | None = None

    @property
    def held(self) -> bool:
        return self.fault is not None

    def hit(self, run: TrialRun, exc: Exception) -> None:
        """A tick of ``run`` raised ``exc``: hold, log and record it."""
        problem = f"{type(exc).__name__}: {exc}"[:300]
        LOGGER.error("session %s: control tick failed: %s", self.code, problem, exc_info=exc)
        self.fault = problem
        detail = {"trial_id": run.trial_id, "error": problem}
        if not self._record("control_fault", detail):
            self._unrecorded = detail  # written once the store takes writes again

    def clear(self) -> bool:
        """The experimenter resumes: write a fault the store refused before, drop the held
        one; True if one was held."""
        if self._unrecorded is not None:
            late, self._unrecorded = self._unrecorded, None
            self._record("control_fault", {**late, "recorded_late": True})
        had, self.fault = self.fault is not None, None
        return had

    def forget(self) -> None:
        """The run the fault held is over (redo, skip, end): nothing to hold any more."""
        self.fault = None

"""What the experimenter's console shows, and what it asks of the server.

The records (:class:`SessionSummary`, :class:`SessionDetail`, :class:`StudyProgress`,
:class:`LinkState`) are built by the live sessions (``study.server.live.console``,
``study.server.live.progress``) and the open link; :class:`Console` is what the console page
(``study.server.console_page``) calls, implemented by ``study.server.server.StudyServer``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class SessionSummary:
    """One row of the sessions list. ``elapsed_s``: session time since the session started
    (``None`` before it started)."""

    code: str
    participant: str
    state: str
    position: str
    connected: bool
    elapsed_s: float | None
    source: str = ""
    """How the participant came: "" (enrolled in the console) or "link" (open enrolment)."""


@dataclass(frozen=True)
class SessionDetail:
    """What the console shows about the selected session."""

    summary: SessionSummary
    schedule: Sequence[tuple[str, str, str]]  # (step label, task, mode)
    cursor: int  # index into schedule of the current step, -1 before the first
    condition: str
    trial_elapsed_s: float
    paused: bool
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    alpha: np.ndarray = field(default_factory=lambda: np.zeros(0))
    confidence: np.ndarray = field(default_factory=lambda: np.zeros(0))
    probabilities: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    goal_names: tuple[str, ...] = ()
    log: Sequence[str] = ()
    fault: str | None = None
    """The control loop's last error while the trial waits for the experimenter to resume."""
    trials: Sequence[tuple[str, int, str, str, str]] = ()
    """Every attempt so far: (label, attempt, status, outcome, duration)."""
    actions: tuple[str, ...] = ()
    """The experimenter actions the session's state allows now."""
    timeline: Sequence[tuple[str, str, str]] = ()
    """Runs and events, oldest first: (clock time, time since the session started, what)."""
    tally: str = ""
    """One line: runs by outcome, pauses, reloads, redos, faults."""
    recruitment: Sequence[tuple[str, str]] = ()
    """Recruitment IDs the participant came with (open enrolment), as (name, value)."""


@dataclass(frozen=True)
class StudyProgress:
    """The study so far, for the top of the console."""

    planned: int | None
    completed: int
    running: int
    stopped: int
    """Withdrawn or ended early."""
    conditions: Sequence[tuple[str, int, int]] = ()
    """Per condition of the task trials: (label, completed runs, successes)."""
    next_row: int = 0
    next_schedule: Sequence[str] = ()
    """The next participant's task trials in order, e.g. "1. easy_right, timid"."""


@dataclass(frozen=True)
class LinkState:
    """The open-enrolment link: on or off, its places and the sessions it opened."""

    enabled: bool
    cap: int
    used: int
    url: str
    refused: tuple[tuple[str, int], ...] = ()
    """New IDs refused since the server started, by why (``OpenLink.refused``)."""


class Console(Protocol):
    def enrol(self, participant: str) -> str: ...
    def summaries(self) -> list[SessionSummary]: ...
    def detail(self, code: str) -> SessionDetail | None: ...
    def act(self, code: str, action: str, *, reason: str = "") -> str: ...
    def reopenable(self) -> list[str]: ...
    def reopen(self, participant: str) -> str: ...
    def progress(self) -> StudyProgress: ...
    def link(self) -> LinkState: ...
    def set_link(self, *, enabled: bool, cap: int) -> LinkState: ...
    def health(self) -> str: ...

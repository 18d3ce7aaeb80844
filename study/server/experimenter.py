"""The experimenter's console (served on 127.0.0.1 only): enrol, control, monitor.

It shows everything the participant must not see: the schedule with conditions, the live
condition, elapsed time, and live plots of alpha, confidence and goal probabilities. The
console reads the server through :class:`Console` (a small protocol implemented by
``study.server.server.StudyServer``) and refreshes itself from a paced thread at ``refresh_hz``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import viser
import viser.uplot as uplot

from study.server.loop import PacedLoop
from study.session import EXPERIMENTER_ACTIONS

LOGGER = logging.getLogger("study.server.experimenter")


@dataclass(frozen=True)
class SessionSummary:
    """One row of the sessions list."""

    code: str
    participant: str
    state: str
    position: str
    connected: bool
    elapsed_s: float


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


class Console(Protocol):
    def enrol(self, participant: str) -> str: ...
    def summaries(self) -> list[SessionSummary]: ...
    def detail(self, code: str) -> SessionDetail | None: ...
    def act(self, code: str, action: str, *, reason: str = "") -> str: ...
    def health(self) -> str: ...


def _fmt_time(seconds: float) -> str:
    m, s = divmod(max(0.0, seconds), 60.0)
    return f"{int(m):02d}:{s:04.1f}"


def sessions_markdown(rows: Sequence[SessionSummary]) -> str:
    if not rows:
        return "_No sessions yet. Enrol a participant to start one._"
    lines = [
        "| code | participant | state | step | tab | elapsed |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        tab = "connected" if r.connected else "-"
        lines.append(
            f"| `{r.code}` | {r.participant} | {r.state} | {r.position} | {tab} |"
            f" {_fmt_time(r.elapsed_s)} |"
        )
    return "\n".join(lines)


def schedule_markdown(detail: SessionDetail) -> str:
    lines = ["| # | step | task | mode |", "|---|---|---|---|"]
    for k, (label, task, mode) in enumerate(detail.schedule):
        mark = "**>**" if k == detail.cursor else ""
        lines.append(f"| {mark} {k + 1} | {label} | {task} | {mode} |")
    return "\n".join(lines)


def trials_markdown(detail: SessionDetail) -> str:
    """Every attempt of the session so far, with how it ended."""
    if not detail.trials:
        return "_No runs yet._"
    lines = ["| run | attempt | status | outcome | time |", "|---|---|---|---|---|"]
    for label, attempt, status, outcome, duration in detail.trials:
        lines.append(f"| {label} | {attempt} | {status} | {outcome} | {duration} |")
    return "\n".join(lines)


class ExperimenterConsole:
    """Builds the console on ``server`` (shared by every experimenter tab) and keeps it fresh."""

    def __init__(self, server: viser.ViserServer, console: Console, *, refresh_hz: float = 5.0):
        self.server = server
        self.console = console
        self.selected: str | None = None
        gui = server.gui
        gui.configure_theme(control_width="large", show_share_button=False)
        gui.main_panel.dock_left()
        gui.main_panel.set_width(820)
        gui.add_markdown("## Experimenter console")
        with gui.add_folder("Sessions"):
            self.sessions_md = gui.add_markdown(sessions_markdown([]))
            self.session_select = gui.add_dropdown("Session", options=("(none)",))
            self.participant_id = gui.add_text("Participant ID", initial_value="")
            self.enrol_button = gui.add_button("Enrol and open session")
            self.enrol_status = gui.add_markdown("")
            self.health_md = gui.add_markdown("")
        self._session_folder = gui.add_folder("Selected session")
        with self._session_folder:
            self.status_md = gui.add_markdown("_Select a session._")
            self.action_group = gui.add_button_group(
                "Action", [a.capitalize() for a in EXPERIMENTER_ACTIONS]
            )
            self.reason = gui.add_text("Reason", initial_value="")
            self.action_status = gui.add_markdown("")
            self.alpha_plot = gui.add_uplot(
                (np.zeros(2), np.zeros(2), np.zeros(2)),
                (
                    uplot.Series(label="t (s)"),
                    uplot.Series(label="alpha", stroke="#d9480f", width=2),
                    uplot.Series(label="confidence", stroke="#1971c2", width=2),
                ),
                title="Arbitration",
                scales={
                    "x": uplot.Scale(time=False),
                    "y": uplot.Scale(auto=False, range=(0.0, 1.0)),
                },
                height=200,
            )
            self.prob_plot: viser.GuiUplotHandle | None = None
            self._prob_goals: tuple[str, ...] = ()
            self.schedule_md = gui.add_markdown("")

        @self.enrol_button.on_click
        def _(_: object) -> None:
            pid = str(self.participant_id.value).strip()
            try:
                code = self.console.enrol(pid)
            except Exception as exc:  # shown to the experimenter; the server keeps running
                self.enrol_status.content = f"**Could not enrol:** {exc}"
                return
            self.enrol_status.content = f"Session for **{pid}**: join code **`{code}`**"
            self.selected = code
            self.refresh()
            self.session_select.value = code

        @self.session_select.on_update
        def _(_: object) -> None:
            value = str(self.session_select.value)
            self.selected = None if value == "(none)" else value
            self.refresh()

        @self.action_group.on_click
        def _(_: object) -> None:
            self._act(str(self.action_group.value).lower())

        self._loop = PacedLoop(self._refresh_safely, rate_hz=refresh_hz, name="console")
        self._loop.start()

    def _act(self, action: str) -> None:
        if self.selected is None:
            self.action_status.content = "_Select a session first._"
            return
        try:
            result = self.console.act(self.selected, action, reason=str(self.reason.value).strip())
        except Exception as exc:
            result = f"**{action} failed:** {exc}"
        self.action_status.content = result
        self.refresh()

    def close(self) -> None:
        self._loop.stop()

    def _refresh_safely(self) -> None:
        try:
            self.refresh()
        except Exception:  # a refresh must never kill the console thread
            LOGGER.exception("console refresh failed")

    def refresh(self) -> None:
        rows = self.console.summaries()
        content = sessions_markdown(rows)
        if self.sessions_md.content != content:
            self.sessions_md.content = content
        health = self.console.health()
        if self.health_md.content != health:
            self.health_md.content = health
        options = ("(none)", *(r.code for r in rows))
        if tuple(self.session_select.options) != options:
            self.session_select.options = options
            if self.selected in options:
                self.session_select.value = self.selected
        if self.selected is None:
            return
        detail = self.console.detail(self.selected)
        if detail is None:
            return
        s = detail.summary
        status = (
            f"**{s.participant}** (code `{s.code}`), state **{s.state}**"
            f"{' (paused)' if detail.paused else ''}; step {s.position}\n\n"
            f"Condition: **{detail.condition}**\n\n"
            f"Session time {_fmt_time(s.elapsed_s)}, trial time"
            f" {_fmt_time(detail.trial_elapsed_s)}; participant tab"
            f" {'connected' if s.connected else 'not connected'}"
        )
        if detail.fault:
            status += (
                f"\n\n**Control error, trial paused:** `{detail.fault}`. Resume to try again;"
                " redo or end if it comes back."
            )
        if detail.log:
            status += "\n\nRecent: " + "; ".join(detail.log[-4:])
        if self.status_md.content != status:
            self.status_md.content = status
        sched = schedule_markdown(detail) + "\n\n" + trials_markdown(detail)
        if self.schedule_md.content != sched:
            self.schedule_md.content = sched
        self._update_plots(detail)

    def _update_plots(self, d: SessionDetail) -> None:
        if len(d.t) < 2:
            return
        self.alpha_plot.data = (d.t, d.alpha, d.confidence)
        if d.goal_names != self._prob_goals or self.prob_plot is None:
            if self.prob_plot is not None:
                self.prob_plot.remove()
            colors = ("#2f9e44", "#e8590c", "#7048e8", "#c2255c")
            with self._session_folder:
                self.prob_plot = self.server.gui.add_uplot(
                    (d.t, *(d.probabilities[:, k] for k in range(len(d.goal_names)))),
                    (
                        uplot.Series(label="t (s)"),
                        *(
                            uplot.Series(label=f"P({name})", stroke=colors[k % 4], width=2)
                            for k, name in enumerate(d.goal_names)
                        ),
                    ),
                    title="Goal probabilities",
                    scales={
                        "x": uplot.Scale(time=False),
                        "y": uplot.Scale(auto=False, range=(0.0, 1.0)),
                    },
                    height=200,
                    order=self.alpha_plot.order + 0.5,
                )
            self._prob_goals = d.goal_names
        else:
            self.prob_plot.data = (d.t, *(d.probabilities[:, k] for k in range(len(d.goal_names))))

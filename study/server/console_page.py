"""The experimenter's console (served on 127.0.0.1 only): a day of sessions from one page.

It shows everything the participant must not see. From the top:

* **Study**: participants completed against the protocol's planned number, success per
  condition, and the next participant's schedule row with its order of conditions;
* **Sessions**: the list, enrolment (the ID field clears once a session is open), and
  reopening a session a server restart or crash interrupted;
* **Open link** (online studies): the open-enrolment link on or off, its places, its URL;
* **Selected session**: its state, condition and session time (from the session's start),
  the actions its state allows (the others are disabled; redo, skip, withdraw and end ask for a
  reason, withdraw and end say that they are final and ask to confirm), its runs and events as
  a timeline (newest first), the live plots of the running trial, and the schedule folded away.

Everything shown under "Selected session" belongs to the selected session: selecting another
clears the plots, the last action's result and the reason before the new one's are drawn.
The console reads the server through :class:`Console` (implemented by
``study.server.server.StudyServer``) and refreshes itself from a paced thread at ``refresh_hz``.
"""

from __future__ import annotations

import logging
import threading
import time

import numpy as np
import viser
import viser.uplot as uplot

from study.server.console_model import Console, SessionDetail, SessionSummary
from study.server.console_texts import (
    link_markdown,
    progress_markdown,
    schedule_markdown,
    sessions_markdown,
    status_markdown,
    timeline_markdown,
    trials_markdown,
)
from study.server.loop import PacedLoop
from study.session import EXPERIMENTER_ACTIONS, NEEDS_REASON

LOGGER = logging.getLogger("study.server.experimenter")

FINAL_ACTIONS = frozenset({"withdraw", "end"})
"""Actions after which the session cannot go on: the console asks to confirm them."""

CONFIRM_TEXT: dict[str, str] = {
    "redo": "**Redo** the current run (or the one just finished)? The earlier attempt is kept,"
    " marked redone.",
    "skip": "**Skip** the current step (a run with its questions, or the questions)?",
    "withdraw": "**Withdraw** {who}? The session ends now and **cannot be continued**;"
    " everything recorded is kept.",
    "end": "**End** the session of {who}? It **cannot be continued** afterwards (a new session"
    " needs a new participant ID); everything recorded is kept.",
}
"""What the console asks before an action that needs a reason (``NEEDS_REASON``)."""


EMPTY_PLOT = (np.array([0.0, 1.0]), np.full(2, np.nan), np.full(2, np.nan))
"""A plot with nothing drawn (uPlot given no points at all keeps a broken x axis after the
first real data arrive)."""


class ExperimenterConsole:
    """Builds the console on ``server`` (shared by every experimenter tab) and keeps it fresh."""

    def __init__(self, server: viser.ViserServer, console: Console, *, refresh_hz: float = 5.0):
        self.server = server
        self.console = console
        self.selected: str | None = None
        self.pending: str | None = None
        """The action waiting for its reason and confirmation."""
        self._results: dict[str, str] = {}
        """The last action's result line per session code."""
        self._options: dict[str, str] = {}
        """Each session code's entry in the session list."""
        self._progress_at = 0.0
        self._lock = threading.RLock()
        """One refresh or selection change at a time (the paced thread against clicks)."""
        gui = server.gui
        gui.configure_theme(control_width="large", show_share_button=False)
        gui.main_panel.dock_left()
        gui.main_panel.set_width(860)
        gui.add_markdown("## Experimenter console")
        with gui.add_folder("Study"):
            self.progress_md = gui.add_markdown("")
        self._build_sessions(gui)
        self._build_link(gui)
        self._session_folder = gui.add_folder("Selected session")
        with self._session_folder:
            self._build_selected(gui)
        self._wire()
        self._loop = PacedLoop(self._refresh_safely, rate_hz=refresh_hz, name="console")
        self._loop.start()

    def _build_sessions(self, gui: viser.GuiApi) -> None:
        """The sessions list, enrolment and reopening."""
        with gui.add_folder("Sessions"):
            self.sessions_md = gui.add_markdown(sessions_markdown([]))
            self.session_select = gui.add_dropdown("Session", options=("(none)",))
            self.participant_id = gui.add_text("Participant ID", initial_value="")
            self.enrol_button = gui.add_button("Enrol and open session")
            self.enrol_status = gui.add_markdown("")
            self.reopen_select = gui.add_dropdown(
                "Interrupted", options=("(none)",), hint="sessions a restart or crash left open"
            )
            self.reopen_button = gui.add_button("Reopen session", disabled=True)
            self.health_md = gui.add_markdown("")

    def _build_link(self, gui: viser.GuiApi) -> None:
        """The open link: on or off, its places."""
        with gui.add_folder("Open link", expand_by_default=False):
            self.link_on = gui.add_checkbox("Open link on", initial_value=False)
            self.link_cap = gui.add_number("Places", initial_value=0, min=0, max=100_000, step=1)
            self.link_md = gui.add_markdown("")

    def _build_selected(self, gui: viser.GuiApi) -> None:
        """The selected session: status, actions, confirmation, timeline, plots, schedule."""
        self.status_md = gui.add_markdown("_Select a session._")
        self.action_buttons = {
            a: gui.add_button(
                a.capitalize(), disabled=True, color="red" if a in FINAL_ACTIONS else None
            )
            for a in EXPERIMENTER_ACTIONS
        }
        self.confirm_md = gui.add_markdown("", visible=False)
        self.reason = gui.add_text("Reason", initial_value="", visible=False)
        self.confirm_button = gui.add_button("Confirm", visible=False, color="red")
        self.cancel_button = gui.add_button("Cancel", visible=False)
        self.action_status = gui.add_markdown("")
        self.timeline_md = gui.add_markdown("")
        self.alpha_plot = gui.add_uplot(
            EMPTY_PLOT,
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
        self.plotted = False
        """Whether the plots show a run (of the selected session)."""
        self.prob_plot: viser.GuiUplotHandle | None = None
        self._prob_goals: tuple[str, ...] = ()
        with gui.add_folder("Schedule and attempts", expand_by_default=False):
            self.schedule_md = gui.add_markdown("")

    def _wire(self) -> None:
        """The console's callbacks."""

        @self.enrol_button.on_click
        def _(_: object) -> None:
            self._enrol(str(self.participant_id.value).strip())

        @self.reopen_button.on_click
        def _(_: object) -> None:
            who = str(self.reopen_select.value)
            if who != "(none)":
                self._enrol(who, verb="Reopened")

        @self.session_select.on_update
        def _(_: object) -> None:
            self.select(_code_of(str(self.session_select.value)))

        for action, button in self.action_buttons.items():
            button.on_click(lambda _e, a=action: self._clicked(a))

        @self.confirm_button.on_click
        def _(_: object) -> None:
            if self.pending is not None:
                self._act(self.pending, reason=str(self.reason.value).strip())

        @self.cancel_button.on_click
        def _(_: object) -> None:
            self._ask(None)

        @self.link_on.on_update
        def _(_: object) -> None:
            self._set_link()

        @self.link_cap.on_update
        def _(_: object) -> None:
            self._set_link()

    # -- actions ---------------------------------------------------------------------------------
    def _enrol(self, pid: str, *, verb: str = "Session for") -> None:
        try:
            code = self.console.enrol(pid)
        except Exception as exc:  # shown to the experimenter; the server keeps running
            self.enrol_status.content = f"**Could not open a session for {pid!r}:** {exc}"
            return
        self.enrol_status.content = f"{verb} **{pid}**: join code **`{code}`**"
        self.participant_id.value = ""  # the next participant's ID starts from an empty field
        self._progress_at = 0.0
        self.refresh()
        self.select(code)
        self.session_select.value = self._option(code)

    def select(self, code: str | None) -> None:
        """Show ``code``'s session (``None``: none) and nothing of the one shown before."""
        with self._lock:
            self._select(code)

    def _select(self, code: str | None) -> None:
        if code == self.selected:
            return
        self.selected = code
        self._ask(None)
        self.action_status.content = self._results.get(code, "") if code else ""
        self._clear_plots()
        self.timeline_md.content = ""
        self.schedule_md.content = ""
        self.status_md.content = "_Select a session._" if code is None else "_Loading..._"
        self.refresh()

    def _option(self, code: str) -> str:
        return self._options.get(code, code)

    def _clicked(self, action: str) -> None:
        if self.selected is None:
            self.action_status.content = "_Select a session first._"
            return
        if action in NEEDS_REASON:
            self._ask(action)
        else:
            self._act(action)

    def _ask(self, action: str | None) -> None:
        """Show the reason field and Confirm for ``action`` (``None``: hide them)."""
        self.pending = action
        shown = action is not None
        if shown:
            who = self._participant_of(self.selected)
            self.confirm_md.content = (
                CONFIRM_TEXT[action].format(who=who) + " Type the reason for the record, then"
                " confirm."
            )
            self.confirm_button.label = f"Confirm {action}"
            self.reason.value = ""
        self.confirm_md.visible = shown
        self.reason.visible = shown
        self.confirm_button.visible = shown
        self.cancel_button.visible = shown

    def _participant_of(self, code: str | None) -> str:
        for row in self.console.summaries():
            if row.code == code:
                return row.participant
        return "this participant"

    def _act(self, action: str, *, reason: str = "") -> None:
        code = self.selected
        if code is None:
            return
        if action in NEEDS_REASON and not reason:
            self.action_status.content = f"**{action.capitalize()} needs a reason:** type it above."
            return
        try:
            result = self.console.act(code, action, reason=reason)
        except Exception as exc:
            result = f"**{action} failed:** {exc}"
        else:
            self._ask(None)
        self._results[code] = result
        if self.selected == code:
            self.action_status.content = result
        self._progress_at = 0.0
        self.refresh()

    def _set_link(self) -> None:
        try:
            cap = int(self.link_cap.value)
            self.console.set_link(enabled=bool(self.link_on.value), cap=cap)
        except Exception as exc:
            self.link_md.content = f"**Could not change the open link:** {exc}"
            return
        self.link_md.content = link_markdown(self.console.link())

    def close(self) -> None:
        self._loop.stop()

    # -- refresh ---------------------------------------------------------------------------------
    def _refresh_safely(self) -> None:
        try:
            self.refresh()
        except Exception:  # a refresh must never kill the console thread
            LOGGER.exception("console refresh failed")

    def refresh(self) -> None:
        with self._lock:
            self._refresh()

    def _refresh(self) -> None:
        rows = self.console.summaries()
        _set(self.sessions_md, sessions_markdown(rows))
        _set(self.health_md, self.console.health())
        options = ("(none)", *(_option(r) for r in rows))
        self._options = {r.code: _option(r) for r in rows}
        if tuple(self.session_select.options) != options:
            self.session_select.options = options
            if self.selected in self._options:
                self.session_select.value = self._options[self.selected]
        now = time.monotonic()
        if now - self._progress_at > 2.0:  # reads every session's trials: not at every refresh
            self._progress_at = now
            self._refresh_study()
        if self.selected is None:
            return
        detail = self.console.detail(self.selected)
        if detail is None or detail.summary.code != self.selected:
            return
        _set(self.status_md, status_markdown(detail))
        for action, button in self.action_buttons.items():
            disabled = action not in detail.actions
            if button.disabled != disabled:
                button.disabled = disabled
        if self.pending is not None and self.pending not in detail.actions:
            self._ask(None)  # the state moved on: what was asked no longer applies
        _set(self.timeline_md, timeline_markdown(detail))
        _set(self.schedule_md, trials_markdown(detail) + "\n\n" + schedule_markdown(detail))
        self._update_plots(detail)

    def _refresh_study(self) -> None:
        _set(self.progress_md, progress_markdown(self.console.progress()))
        waiting = ("(none)", *self.console.reopenable())
        if tuple(self.reopen_select.options) != waiting:
            self.reopen_select.options = waiting
        self.reopen_button.disabled = len(waiting) == 1
        link = self.console.link()
        if bool(self.link_on.value) != link.enabled:
            self.link_on.value = link.enabled
        if int(self.link_cap.value) != link.cap:
            self.link_cap.value = link.cap
        _set(self.link_md, link_markdown(link))

    def _clear_plots(self) -> None:
        self.plotted = False
        self.alpha_plot.data = EMPTY_PLOT
        if self.prob_plot is not None:
            self.prob_plot.remove()
            self.prob_plot = None
        self._prob_goals = ()

    def _update_plots(self, d: SessionDetail) -> None:
        if len(d.t) < 2:
            if self.plotted:
                self._clear_plots()  # this session has no run to plot (yet, or any more)
            return
        self.plotted = True
        self.alpha_plot.data = (d.t, d.alpha, d.confidence)
        if d.goal_names != self._prob_goals or self.prob_plot is None:
            if self.prob_plot is not None:
                self.prob_plot.remove()
                self.prob_plot = None
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


def _option(row: SessionSummary) -> str:
    """A session's entry in the session list: participant and code."""
    return f"{row.participant} ({row.code})"


def _code_of(option: str) -> str | None:
    """The session code of a session-list entry (``None`` for "(none)")."""
    if not option.endswith(")") or "(" not in option or option == "(none)":
        return None
    return option[option.rindex("(") + 1 : -1]


def _set(handle: viser.GuiMarkdownHandle, content: str) -> None:
    if handle.content != content:
        handle.content = content

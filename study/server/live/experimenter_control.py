"""``ExperimenterControl``: the console's actions on one live session.

Each of ``study.session.EXPERIMENTER_ACTIONS`` goes to the session (those in ``NEEDS_REASON``
only with a reason: an empty one is refused, never filled in); around it the live parts
that the session does not know of: a pause freezes the participant's input first; a resume
waits until the store takes this session's samples again, writes a control fault the store
refused earlier and drops the held fault, which is the whole resume when the fault left the
session unpaused (a full disk refuses the pause's own event).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from study.server.live.control_faults import ControlFaults
from study.server.live.controls import LiveInput
from study.server.participant_page import ParticipantPage
from study.session import EXPERIMENTER_ACTIONS, NEEDS_REASON, Session, TrialRun, check_reason


class ExperimenterControl:
    """Experimenter actions on one live session (see module docstring)."""

    def __init__(
        self,
        *,
        session: Session,
        faults: ControlFaults,
        input: LiveInput,
        tab: Callable[[], tuple[ParticipantPage | None, TrialRun | None]],
        wake: Callable[[], None],
    ) -> None:
        self.session = session
        self.faults = faults
        self.input = input
        self._tab = tab
        """The bound tab and the current run now."""
        self._wake = wake
        """Wake the page thread (the screen changed)."""

    def act(self, action: str, *, reason: str = "") -> str:
        """Run ``action``; returns a line for the console (errors raise)."""
        s = self.session
        if action not in EXPERIMENTER_ACTIONS:
            actions = ", ".join(EXPERIMENTER_ACTIONS)
            raise ValueError(f"unknown action {action!r}; use one of {actions}")
        if action in NEEDS_REASON:
            getattr(s, action)(reason=check_reason(reason, action))
        elif action == "start":
            s.start()
        elif action == "pause":
            page, _ = self._tab()
            self.input.freeze(page)
            s.pause()
        else:  # resume
            self.store_takes_writes()
            had_fault = self.faults.clear()
            _, run = self._tab()
            if had_fault and run is not None and not run.over and not run.paused:
                self._wake()
                return f"{time.strftime('%H:%M:%S')} resume: control loop running again"
            s.resume()
        self._wake()
        return f"{time.strftime('%H:%M:%S')} {action}: done"

    def store_takes_writes(self, *, wait_s: float = 1.0) -> None:
        """Raise while the store still refuses this session's samples (a full or read-only
        disk); the writer retries every batch period, so give it ``wait_s`` to catch up."""
        deadline = time.monotonic() + wait_s
        while (error := self.session.samples_error) is not None:
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"the store still refuses writes ({error}); free space or fix the folder,"
                    " then resume again"
                )
            time.sleep(0.05)

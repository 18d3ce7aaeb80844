"""Places of the open link held by sessions nobody uses: given back.

Anyone with the link can make up recruitment IDs; a script from 8 addresses once filled 50
places in 20 s, and each of those sessions kept its place, its lease and its threads for as long
as the server ran, so a real participant then found the link full. A link session that has not
got past consent (no trial, no answer) and has had no tab for ``LINK_IDLE_S`` is closed and its
place given back; the store records it (event ``link_place_released``), so a restart does not
count it again. If its recruitment ID comes back, the session is opened again under the same
pseudonym and holds a place again, even when the link has filled meanwhile: that person was let
in first.

``PlaceSweeper`` runs the check every ``SWEEP_S`` while the server runs (the study server's
sweeper also lets finished sessions go: ``study.server.finished_sessions``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable

from study.server.live import LiveSession
from study.server.open_link import RELEASED

LOGGER = logging.getLogger("study.server.server")

LINK_IDLE_S = 600.0
"""How long a link session that never got past consent keeps its place without a tab (ten
minutes: a reload, a lost connection or a participant reading elsewhere comes back sooner)."""
SWEEP_S = 30.0
NOT_BEGUN = ("waiting", "consent")
"""Phases of a session whose participant has not agreed to take part yet."""


def idle_link_sessions(
    sessions: Iterable[LiveSession], *, idle_s: float, now: float
) -> list[LiveSession]:
    """The open link's sessions that have not got past consent and have had no tab for at
    least ``idle_s`` seconds at ``now`` (``time.monotonic()``)."""
    return [
        live
        for live in sessions
        if live.recruitment
        and not live.closed
        and live.unattended_s(now) >= idle_s
        and live.session.phase() in NOT_BEGUN
    ]


class PlaceSweeper:
    """Calls ``sweep`` every ``period_s`` on a daemon thread until ``stop``; an exception is
    logged, never raised (the next sweep tries again)."""

    def __init__(
        self, sweep: Callable[[], object], *, period_s: float = SWEEP_S, name: str = "link-places"
    ) -> None:
        self._sweep = sweep
        self._period = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join()

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            started = time.monotonic()
            try:
                self._sweep()
            except Exception:
                LOGGER.exception("the sweep of idle link places and finished sessions failed")
            if time.monotonic() - started > self._period:  # pragma: no cover - a stuck store
                LOGGER.warning(
                    "the sweep of idle link places and finished sessions took over %.0f s",
                    self._period,
                )


__all__ = ["LINK_IDLE_S", "RELEASED", "PlaceSweeper", "idle_link_sessions"]

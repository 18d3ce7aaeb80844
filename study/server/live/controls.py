"""``LiveInput``: the participant's input to the running trial, frozen while it is paused.

The gizmo, the steering keys and the grasp (button or G) feed one ``ParticipantInput``. Any
pause (the experimenter, a lost tab, a control fault) freezes it and hides the handle; on
resume the handle is back, shown: on the participant's own target in the absolute mapping (a
pause leaves it where they put it, wherever the robot took the gripper), on the gripper in the
relative one (``ParticipantInput.resume_at``). Whether the input is
frozen is the input's own state (``ParticipantInput.frozen``); whether the session is paused is
the session's (``Session.paused``): nothing here keeps a second copy.

An input refused while frozen is logged as an ``input_rejected`` event (rate-limited by the
session) from one worker thread: input callbacks run on viser's event loop, which a store
write must never hold up.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from app.teleop.errors import TeleopError
from app.teleop.keyboard import KEYMAP
from app.teleop.participant_input import InputFrozen, ParticipantInput
from app.teleop.reach import ReachRegion
from study.server.participant_page import ParticipantPage

LOGGER = logging.getLogger("study.server.live")


class LiveInput:
    """One live session's participant input (see module docstring)."""

    def __init__(self, *, code: str, record: Callable[[str, Mapping[str, Any]], bool]) -> None:
        self.source: ParticipantInput | None = None
        self._record = record
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"events-{code}")

    @property
    def frozen(self) -> bool:
        return self.source is not None and self.source.frozen

    def take(self) -> ParticipantInput | None:
        """End of a run: no trial, no input (keys do nothing); the old source, frozen."""
        source, self.source = self.source, None
        if source is not None:
            source.freeze()
        return source

    def freeze(self, page: ParticipantPage | None) -> None:
        """Freeze the input and hide the handle (idempotent)."""
        if self.source is not None:
            self.source.freeze()
        if page is not None:
            page.show_gizmo(False)

    def thaw(
        self, page: ParticipantPage | None, gripper: np.ndarray, *, reach: ReachRegion | None = None
    ) -> None:
        """Thaw the input, the ``gripper`` where the pause left it; the handle back where
        ``ParticipantInput.resume_at`` says and shown -- inside the ``reach``: a handle let go
        past it during the pause goes back over the point the arm is sent to, as a release
        outside a pause does (the target becomes that point)."""
        source = self.source
        if source is None:
            return
        source.thaw()
        at = gripper
        try:
            at = source.resume_at(gripper)
        except (InputFrozen, TeleopError):
            LOGGER.debug("could not put the handle back", exc_info=True)
        if reach is not None:
            at = self.keep_inside(at, reach)
        if page is not None:
            page.move_gizmo(at)
            page.show_gizmo(True)

    def keep_inside(self, at: np.ndarray, reach: ReachRegion) -> np.ndarray:
        """An absolute handle left at ``at`` past the ``reach`` goes back over the point the arm
        is sent to (the reach clamps it), and that point becomes the target; returns where the
        handle is to be drawn. (A relative handle returns to the gripper, which the reach bounds
        already; that point sent to it would be a new displacement.)"""
        source = self.source
        if source is None or source.relative or reach.contains(at):
            return at
        inside = reach.clamp(at)
        try:
            source.place(inside)
        except (InputFrozen, TeleopError) as exc:
            self._refused(exc)
        return inside

    # ---- viser callbacks ----------------------------------------------------------------------
    def grasp(self) -> None:
        source = self.source
        if source is None:
            return
        try:
            source.request_grasp()
        except InputFrozen as exc:
            self._refused(exc)

    def on_target(self, target: np.ndarray) -> None:
        source = self.source
        if source is None:
            return
        try:
            source.set_target(target)
        except (InputFrozen, TeleopError) as exc:
            self._refused(exc)

    def on_release(self) -> None:
        """The participant let go of the handle (it returns to the gripper if relative)."""
        if self.source is not None:
            self.source.let_go()

    def on_keys(
        self, down: frozenset[str], up: frozenset[str], *, reframe: Callable[[], None]
    ) -> None:
        """Key-state changes from the page: steering keys to the input, G grasps, V re-frames."""
        source = self.source
        if source is not None:
            for key in up & set(KEYMAP):
                source.key_up(key)
        if "v" in down:
            reframe()
        if source is None:
            return
        for key in sorted(down):
            try:
                if key == "g":
                    source.request_grasp()
                elif key in KEYMAP:
                    source.key_down(key)
            except InputFrozen as exc:
                self._refused(exc)

    def let_go(self, keys: frozenset[str]) -> None:
        """Keys whose state stopped arriving (``ParticipantPage.expire_keys``): released, and
        those the input still held recorded as a ``keys_expired`` event."""
        source = self.source
        if source is None:
            return
        held = keys & source.keyboard.held  # a key a pause let go of moved nothing since
        for key in keys & set(KEYMAP):
            source.key_up(key)
        if held:
            with contextlib.suppress(RuntimeError):
                self._pool.submit(self._record, "keys_expired", {"keys": "".join(sorted(held))})

    def dropped(self, reason: str) -> None:
        """The port's firewall refused a message of this session's tab (any thread; recorded
        as an ``input_dropped`` event from the worker thread)."""
        with contextlib.suppress(RuntimeError):  # closing: the worker is gone
            self._pool.submit(self._record, "input_dropped", {"reason": reason[:200]})

    def _refused(self, exc: Exception) -> None:
        problem = str(exc)[:200]
        with contextlib.suppress(RuntimeError):  # closing: the worker is gone
            self._pool.submit(self._record, "input_rejected", {"problem": problem})

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

"""The participant's page: one screen at a time in the viser panel, plus the teleop gizmo.

The page only shows and asks; it decides nothing. The server's session controller calls
``show_*`` to change the screen and receives answers through the callbacks it passes. Every
string shown goes through :func:`app.ui.blinding.check_text` first (a condition word raises),
and the blinding guard checks every message again on the wire. Callbacks of a screen that is
no longer shown are ignored, so a late click can never answer the next screen.

Keyboard (second input): W/S move the target away/back, A/D sideways, R/F up/down, G grasp.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import viser

from app.ui.blinding import check_text

LOGGER = logging.getLogger("app.ui.participant")

KEY_STEP_M = 0.02
"""Keyboard nudge of the target per key press, metres."""

KEY_NUDGES: dict[str, tuple[float, float, float]] = {
    "W": (KEY_STEP_M, 0.0, 0.0),
    "S": (-KEY_STEP_M, 0.0, 0.0),
    "A": (0.0, KEY_STEP_M, 0.0),
    "D": (0.0, -KEY_STEP_M, 0.0),
    "R": (0.0, 0.0, KEY_STEP_M),
    "F": (0.0, 0.0, -KEY_STEP_M),
}
KEY_HELP = (
    "Drag the arrows of the handle at the gripper to move it, or use the keys "
    "**W**/**S** (away / back), **A**/**D** (sideways), **R**/**F** (up / down). "
    "Press **G** or the button below to close or open the gripper."
)


class InputRejected(ValueError):
    """A message from the browser was malformed (NaN pose, unknown answer); it was ignored."""


@dataclass(frozen=True)
class LikertItem:
    """A k-point item: ``key`` stays on the server; ``prompt`` and ``anchors`` (answer ``j``
    means ``anchors[j - 1]``) are shown."""

    key: str
    prompt: str
    anchors: tuple[str, ...]

    @property
    def points(self) -> int:
        return len(self.anchors)

    def anchor_text(self) -> str:
        """The two end anchors, and the middle one when the scale has an odd length."""
        k = self.points
        marks = [1, k] if k % 2 == 0 else [1, (k + 1) // 2, k]
        return " · ".join(f"{j} = {self.anchors[j - 1]}" for j in marks)


def parse_answer(value: object, *, points: int) -> int:
    """The integer answer 1..points in ``value`` (a button label), else :class:`InputRejected`."""
    try:
        answer = int(str(value))
    except ValueError:
        raise InputRejected(f"answer {value!r} is not a number 1..{points}") from None
    if not 1 <= answer <= points:
        raise InputRejected(f"answer {answer} is outside 1..{points}")
    return answer


def parse_position(position: object) -> np.ndarray:
    """A finite 3-vector from a gizmo pose, else :class:`InputRejected`."""
    try:
        p = np.asarray(position, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputRejected(f"gizmo position {position!r} is not numeric") from None
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InputRejected(f"gizmo position {p.tolist()} is not a finite 3-vector")
    return p


class ParticipantPage:
    """What one participant's browser tab shows."""

    def __init__(self, client: viser.ClientHandle, *, title: str) -> None:
        self.client = client
        self.title = check_text(title)
        self.screen = 0
        self.screen_name = "none"
        self._lock = threading.RLock()
        self._handles: list[object] = []
        self._gizmo: viser.TransformControlsHandle | None = None
        self._commands: list[object] = []
        self.rejected: list[str] = []
        self.asks_code = False
        self.on_reject: Callable[[str], None] | None = None
        """Called with each rejected input's problem (the server records it as an event)."""

    # -- plumbing ----------------------------------------------------------------------------
    def _new_screen(self, name: str) -> int:
        with self._lock:
            for h in self._handles:
                with contextlib.suppress(Exception):
                    h.remove()  # type: ignore[attr-defined]
            self._handles = []
            self.screen += 1
            self.screen_name = name
            return self.screen

    def _md(self, text: str) -> viser.GuiMarkdownHandle:
        h = self.client.gui.add_markdown(check_text(text))
        self._handles.append(h)
        return h

    def _button(self, label: str, *, disabled: bool = False) -> viser.GuiButtonHandle:
        h = self.client.gui.add_button(check_text(label), disabled=disabled)
        self._handles.append(h)
        return h

    def _current(self, screen: int) -> bool:
        return screen == self.screen

    def reject(self, problem: str) -> None:
        """Tell the participant an input was ignored (the server keeps running)."""
        self.rejected.append(problem)
        LOGGER.warning("participant client %s: rejected input: %s", self.client.client_id, problem)
        if self.on_reject is not None:
            with contextlib.suppress(Exception):
                self.on_reject(problem)
        with contextlib.suppress(Exception):
            self.client.add_notification(
                "Input ignored",
                "That input could not be used; please try again.",
                auto_close_seconds=3.0,
                color="orange",
            )

    def _header(self, progress: str | None) -> None:
        self._md(f"### {self.title}" + (f"\n\n{progress}" if progress else ""))

    # -- screens -----------------------------------------------------------------------------
    def show_message(
        self,
        heading: str,
        body: str,
        *,
        progress: str | None = None,
        button: str | None = None,
        on_button: Callable[[], None] | None = None,
    ) -> int:
        """A heading, a paragraph, and optionally one button."""
        with self._lock:
            screen = self._new_screen("message:" + heading)
            self._header(progress)
            self._md(f"**{heading}**\n\n{body}")
            if button is not None and on_button is not None:
                b = self._button(button)

                @b.on_click
                def _(_: object) -> None:
                    if self._current(screen):
                        b.disabled = True
                        on_button()

            return screen

    def show_join(self, *, ask_code: bool, on_code: Callable[[str], None]) -> int:
        """Waiting for a session; with several running, ask for the join code."""
        with self._lock:
            screen = self._new_screen("join")
            self.asks_code = ask_code
            self._header(None)
            if not ask_code:
                self._md("**Welcome.**\n\nPlease wait: the experimenter will start your session.")
                return screen
            self._md("**Welcome.**\n\nPlease type the join code the experimenter gives you.")
            text = self.client.gui.add_text(check_text("Join code"), initial_value="")
            self._handles.append(text)
            b = self._button("Join")

            @b.on_click
            def _(_: object) -> None:
                if self._current(screen):
                    on_code(str(text.value).strip())

            return screen

    def show_consent(self, text: str, *, on_agree: Callable[[], None]) -> int:
        return self.show_message("Consent", text, button="I agree", on_button=on_agree)

    def show_questions(
        self,
        heading: str,
        intro: str,
        items: Sequence[LikertItem],
        *,
        progress: str | None,
        on_submit: Callable[[dict[str, int]], None],
    ) -> int:
        """Likert items as 1..7 button rows with their anchors; Continue needs every answer."""
        with self._lock:
            screen = self._new_screen("questions:" + heading)
            self._header(progress)
            self._md(f"**{heading}**\n\n{intro}")
            answers: dict[str, int] = {}
            submit = None
            for index, item in enumerate(items, 1):
                self._md(f"**{item.prompt}**\n\n{item.anchor_text()}")
                group = self.client.gui.add_button_group(
                    f"Answer {index}",
                    [str(k) for k in range(1, item.points + 1)],
                )
                self._handles.append(group)
                chosen = self._md("Your answer: none yet")

                def on_click(event: object, item: LikertItem = item, group=group, chosen=chosen):
                    if not self._current(screen):
                        return
                    try:
                        answers[item.key] = parse_answer(group.value, points=item.points)
                    except InputRejected as exc:
                        self.reject(str(exc))
                        return
                    chosen.content = f"Your answer: **{answers[item.key]}**"
                    if submit is not None and len(answers) == len(items):
                        submit.disabled = False

                group.on_click(on_click)
            submit = self._button("Continue", disabled=True)

            @submit.on_click
            def _(_: object) -> None:
                if not self._current(screen):
                    return
                if len(answers) != len(items):
                    self.reject("not every item has an answer")
                    return
                submit.disabled = True
                on_submit(dict(answers))

            return screen

    def show_trial(
        self, *, heading: str, instruction: str, progress: str | None, on_grasp: Callable[[], None]
    ) -> int:
        """The trial screen: the instruction, key help and a grasp button."""
        with self._lock:
            screen = self._new_screen("trial:" + heading)
            self._header(progress)
            self._md(f"**{heading}**\n\n{instruction}\n\n{KEY_HELP}")
            b = self._button("Grasp / release (G)")

            @b.on_click
            def _(_: object) -> None:
                if self._current(screen):
                    on_grasp()

            return screen

    # -- teleoperation -----------------------------------------------------------------------
    def add_gizmo(
        self, position: np.ndarray, *, on_target: Callable[[np.ndarray], None], scale: float = 0.3
    ) -> viser.TransformControlsHandle:
        """The transform handle at the end effector; every pose update goes to ``on_target``."""
        with self._lock:
            self.remove_gizmo()
            gizmo = self.client.scene.add_transform_controls(
                "/handle",
                scale=scale,
                disable_rotations=True,
                depth_test=False,
                position=tuple(np.asarray(position, float)),
            )
            self._gizmo = gizmo

        # async: runs on viser's event loop in arrival order (thread-pool callbacks may run
        # out of order, and a stale pose must never overwrite a newer one); ``on_target`` only
        # takes a lock. A rejection (notice + store event) goes to a worker thread.
        @gizmo.on_update
        async def _(event: object) -> None:
            try:
                target = parse_position(gizmo.position)
            except InputRejected as exc:
                asyncio.get_running_loop().run_in_executor(None, self.reject, str(exc))
                return
            on_target(target)

        return gizmo

    def move_gizmo(self, position: np.ndarray) -> None:
        with self._lock:
            if self._gizmo is not None:
                self._gizmo.position = tuple(np.asarray(position, float))

    def remove_gizmo(self) -> None:
        with self._lock:
            if self._gizmo is not None:
                with contextlib.suppress(Exception):
                    self._gizmo.remove()
                self._gizmo = None

    def add_keys(
        self, *, on_nudge: Callable[[np.ndarray], None], on_grasp: Callable[[], None]
    ) -> None:
        """Hotkeys: W/S/A/D/R/F nudge the target, G toggles the gripper."""
        with self._lock:
            if self._commands:
                return
            for key, delta in KEY_NUDGES.items():
                cmd = self.client.gui.add_command(f"Move {key}", hotkey=key)  # type: ignore[arg-type]
                cmd.on_trigger(lambda _e, d=delta: on_nudge(np.array(d)))
                self._commands.append(cmd)
            cmd = self.client.gui.add_command("Grasp", hotkey="G")
            cmd.on_trigger(lambda _e: on_grasp())
            self._commands.append(cmd)

    def remove_keys(self) -> None:
        with self._lock:
            for cmd in self._commands:
                with contextlib.suppress(Exception):
                    cmd.remove()  # type: ignore[attr-defined]
            self._commands = []

"""The participant's page: one screen at a time in the viser panel, plus the teleop handle
(:mod:`study.server.page_handle`).

The page only shows and asks; it decides nothing. The server's session controller calls
``show_*`` to change the screen and receives answers through the callbacks it passes. Every
string shown goes through :func:`study.server.blinding_guard.check_text` first (a condition word raises),
and the blinding guard checks every message again on the wire. Callbacks of a screen that is
no longer shown are ignored, so a late click can never answer the next screen.

Keyboard (second input): while W/S, A/D or R/F is held the target moves away/back, sideways or
up/down; G grasps, V brings back the task view. The keys travel through the page script
(:mod:`study.server.page_script`), which keeps them from viser's camera, as the value of one hidden
text element: ``"<seq> <held keys>"``, resent every 250 ms while a key is held (and for a
second after each change), so a lost message costs at most one period; :meth:`ParticipantPage._on_key_state`
turns each new value into key-down and key-up calls, and :meth:`ParticipantPage.expire_keys`
lets go of keys whose state has not been heard for a while the server listened on time
(:mod:`study.server.listening`: a stalled connection never leaves the arm moving, a slow
server never lets go of an honest participant's key).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence

import numpy as np
import viser

from study.protocol import Item, LikertItem
from study.server import viser_door
from study.server.answer_fields import add_answer_field
from study.server.blinding_guard import check_text
from study.server.draw_rate import draw_rate_script
from study.server.listening import ListeningClock
from study.server.page_handle import TeleopHandle
from study.server.page_inputs import (
    InputRejected,
    parse_draw_rate,
    parse_key_state,
)
from study.server.page_script import page_script

LOGGER = logging.getLogger("study.server.participant")

KEY_HELP = (
    "Drag an arrow or a square of the handle above the gripper to move it, or hold the keys "
    "**W**/**S** (away / back), **A**/**D** (sideways), **R**/**F** (up / down). "
    "The handle and the keys move the gripper anywhere inside the frame drawn on the table. "
    "Press **G** or the button above to close the gripper around the object; the arm then "
    "lifts it. The picture shows the table from above. Drag the background to "
    "look around, scroll to zoom; **V** brings back the starting view."
)
KEYS_BEFORE_START = (
    "Once you press Start: drag the handle above the gripper to move it, or hold the keys "
    "**W**/**S** (away / back), **A**/**D** (sideways), **R**/**F** (up / down). "
    "Press **G** to close the gripper around the object; the arm then lifts it."
)
"""The keys on the screen before a run (the Start screen), so they are known before the run's
clock starts; the run's screen shows :data:`KEY_HELP`."""
GRASP_LABEL = "Close the gripper (G)"
GRIPPER_CLOSED_LABEL = "Gripper closed"
"""The grasp button's label while the gripper is closed (closing, closed on nothing, lifting):
greyed, so that a participant sees at once that the key or the click was taken."""
INSET_SIZE = (320, 240)
"""Width and height (pixels) of the view from above on the trial screen."""
DEAF_LIMIT_S = 3.0
"""Held keys go this long after their last state even while the server was behind: a stalled
tab on a starved server must not move the arm for longer (``expire_keys``)."""

DECLINE = "I do not wish to take part"


def message_screen(heading: str) -> str:
    """The name of the message screen with ``heading`` (``ParticipantPage.screen_name``)."""
    return "message:" + heading


class ParticipantPage:
    """What one participant's browser tab shows."""

    def __init__(
        self,
        client: viser.ClientHandle,
        *,
        title: str,
        words: Iterable[str],
        listening: ListeningClock | None = None,
    ) -> None:
        self.client = client
        self.listening = listening
        """The port's event loop on time or behind: silence is counted while it listened
        (``expire_keys``); ``None`` counts wall time."""
        self.words = tuple(words)
        """The blinded vocabulary every text shown is checked against."""
        self.title = check_text(title, words=self.words)
        self.screen = 0
        self.screen_name = "none"
        self._lock = threading.RLock()
        self.handle = TeleopHandle(client, lock=self._lock, reject=self.reject)
        """The teleoperation handle on the tab's scene."""
        self._handles: list[object] = []
        self._clock: viser.GuiMarkdownHandle | None = None
        self._clock_text = ""
        self._inset: viser.GuiImageHandle | None = None
        self._grasp: viser.GuiButtonHandle | None = None
        self._grasp_closed = False
        self._notice: object | None = None
        self._screen_notes: list[tuple[str, object]] = []
        self.rejected: deque[str] = deque(maxlen=50)
        self.asks_code = False
        self.address = "unknown"
        """The network address the tab connected from (set by the server)."""
        self.on_reject: Callable[[str], None] | None = None
        """Called with each rejected input's problem (the server records it as an event)."""
        self.on_keys: Callable[[frozenset[str], frozenset[str]], None] | None = None
        """Called with (keys that went down, keys that went up) on each key-state change."""
        self._key_seq = -1
        self._keys_held: frozenset[str] = frozenset()
        self._keys_heard_at = 0.0
        self._keys_lock = threading.Lock()
        self._keys = client.gui.add_text("keys", initial_value="", visible=False)
        self._keys.on_update(self._on_key_state)
        self.draw_hz: float | None = None
        """Frames a second the page draws, as it last said (:mod:`study.server.draw_rate`);
        ``None`` until it does."""
        self._draw_rate = client.gui.add_text("fps", initial_value="", visible=False)
        self._draw_rate.on_update(self._on_draw_rate)
        client.gui.set_panel_label(self.title)
        keys_uuid = viser_door.element_uuid(self._keys)
        self.run_script(
            page_script(keys_uuid=keys_uuid, title=self.title)
            + draw_rate_script(uuid=viser_door.element_uuid(self._draw_rate))
        )

    def run_script(self, source: str) -> None:
        """Run ``source`` (JavaScript) in this tab once (checked for condition words too)."""
        viser_door.run_javascript(self.client, check_text(source, words=self.words))

    async def _on_draw_rate(self, _event: object) -> None:
        """The page's drawing rate (frames a second) from the page script (async: parsed on
        the event loop, no thread per message; a refusal is recorded off it)."""
        try:
            self.draw_hz = parse_draw_rate(self._draw_rate.value)
        except InputRejected as exc:
            asyncio.get_running_loop().run_in_executor(None, self.reject, str(exc), False)

    async def _on_key_state(self, _event: object) -> None:
        """A new key state from the page script (async: in arrival order, never reordered)."""
        try:
            seq, held = parse_key_state(self._keys.value)
        except InputRejected as exc:
            asyncio.get_running_loop().run_in_executor(None, self.reject, str(exc), False)
            return
        with self._keys_lock:
            if seq <= self._key_seq:
                return  # a reload restarts the count: a new page object starts at -1
            self._key_seq = seq
            self._keys_heard_at = time.monotonic()
            down, up = held - self._keys_held, self._keys_held - held
            self._keys_held = held
        if self.on_keys is not None and (down or up):
            self.on_keys(down, up)  # in arrival order: a key's up never overtakes its down

    def expire_keys(self, max_age_s: float) -> frozenset[str]:
        """Let go of the held keys if the page has been silent for more than ``max_age_s``
        (it resends their state every 250 ms while a key is held); returns the keys let go. A
        later state that still holds them presses them again. Silent: while the server
        listened (``listening``): a state waiting in the server's own backlog was sent on
        time; past ``DEAF_LIMIT_S`` since the last state they go whatever the server's lag."""
        if not self._keys_held:
            return frozenset()
        with self._keys_lock:
            heard, now = self._keys_heard_at, time.monotonic()
            age = now - heard
            if age <= max_age_s:
                return frozenset()
            if (
                self.listening is not None
                and age <= DEAF_LIMIT_S
                and self.listening.silent_s(heard, now) <= max_age_s
            ):
                return frozenset()
            held, self._keys_held = self._keys_held, frozenset()
            return held

    # -- plumbing ----------------------------------------------------------------------------
    def _new_screen(self, name: str) -> int:
        with self._lock:
            for h in self._handles:
                with contextlib.suppress(Exception):
                    h.remove()  # type: ignore[attr-defined]
            self._handles = []
            kept = []
            for shown_on, note in self._screen_notes:
                if shown_on == name:
                    kept.append((shown_on, note))
                    continue
                with contextlib.suppress(Exception):
                    note.remove()  # type: ignore[attr-defined]
            self._screen_notes = kept
            self._clock = self._inset = self._grasp = None
            self._clock_text = ""
            self._grasp_closed = False
            self.screen += 1
            self.screen_name = name
            return self.screen

    def _md(self, text: str) -> viser.GuiMarkdownHandle:
        h = self.client.gui.add_markdown(check_text(text, words=self.words))
        self._handles.append(h)
        return h

    def _button(self, label: str, *, disabled: bool = False) -> viser.GuiButtonHandle:
        h = self.client.gui.add_button(check_text(label, words=self.words), disabled=disabled)
        self._handles.append(h)
        return h

    def _current(self, screen: int) -> bool:
        return screen == self.screen

    def reject(self, problem: str, notify: bool = True) -> None:
        """Record an ignored input (the server keeps running); ``notify`` tells the participant."""
        problem = problem[:200]
        self.rejected.append(problem)
        LOGGER.debug("participant client %s: rejected input: %s", self.client.client_id, problem)
        if self.on_reject is not None:
            with contextlib.suppress(Exception):
                self.on_reject(problem)
        if not notify:
            return
        with contextlib.suppress(Exception):
            self.client.add_notification(
                "Input ignored",
                "That input could not be used; please try again.",
                auto_close_seconds=3.0,
                color="orange",
            )

    def notify(self, text: str, *, seconds: float = 3.0, screen: str | None = None) -> None:
        """A short notice in the corner of the page (it closes by itself); with ``screen`` (a
        screen's name, :func:`message_screen`) it also goes as soon as another screen shows:
        a run's outcome stayed over the questions and the next run's Start screen."""
        with contextlib.suppress(Exception):
            note = self.client.add_notification(
                check_text(text, words=self.words), "", auto_close_seconds=seconds, color="blue"
            )
            if screen is not None:
                with self._lock:
                    self._screen_notes.append((screen, note))

    def hold_notice(self, text: str | None) -> None:
        """A notice that stays while ``text`` is given and goes with ``None`` (one at a time:
        a new text replaces the old one)."""
        with self._lock:
            old, self._notice = self._notice, None
            if old is not None:
                with contextlib.suppress(Exception):
                    old.remove()  # type: ignore[attr-defined]
            if text is None:
                return
            with contextlib.suppress(Exception):
                self._notice = self.client.add_notification(
                    check_text(text, words=self.words),
                    "",
                    auto_close_seconds=None,
                    with_close_button=False,
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
        choices: Sequence[tuple[str, Callable[[], None]]] = (),
    ) -> int:
        """A heading, a paragraph, and optionally one button (or several ``choices``); the
        first click on the screen disables them all, so a double click acts once."""
        with self._lock:
            screen = self._new_screen(message_screen(heading))
            self._header(progress)
            self._md(f"**{heading}**\n\n{body}")
            options = list(choices)
            if button is not None and on_button is not None:
                options.insert(0, (button, on_button))
            buttons = [self._button(label) for label, _ in options]
            claimed = threading.Lock()  # the first click on this screen wins, once
            for b, (_, action) in zip(buttons, options, strict=True):

                def click(_: object, action: Callable[[], None] = action) -> None:
                    if self._current(screen) and claimed.acquire(blocking=False):
                        for x in buttons:
                            x.disabled = True
                        action()

                b.on_click(click)
            return screen

    def show_join(
        self, *, ask_code: bool, on_code: Callable[[str], None], notice: str | None = None
    ) -> int:
        """Before a session: ask for the join code (or, on a kiosk, ask to wait)."""
        with self._lock:
            screen = self._new_screen("join")
            self.asks_code = ask_code
            self._header(None)
            if not ask_code:
                self._md(
                    "**Welcome.**\n\nPlease wait: the experimenter will start your session"
                    " in a moment. This page will change by itself."
                )
                return screen
            self._md(
                "**Welcome.**\n\nPlease type the join code the experimenter gives you (six"
                " letters and digits), then press Join." + (f"\n\n_{notice}_" if notice else "")
            )
            # no hint: viser shows it as a tooltip over the lines above, the notice among them
            text = self.client.gui.add_text(
                check_text("Join code", words=self.words), initial_value=""
            )
            self._handles.append(text)
            b = self._button("Join")

            @b.on_click
            def _(_: object) -> None:
                if self._current(screen):
                    on_code(str(text.value).strip())

            return screen

    def show_consent(
        self,
        text: str,
        *,
        on_agree: Callable[[], None],
        agree: str = "I agree",
        on_decline: Callable[[], None] | None = None,
    ) -> int:
        """The consent text with its agree button and, with ``on_decline``, a way to say no
        (asked once more before it ends the session)."""
        if on_decline is None:
            return self.show_message("Consent", text, button=agree, on_button=on_agree)

        def confirm() -> None:
            self.show_message(
                "Not taking part",
                "You can stop now: nothing has been recorded about you yet except this"
                " decision. Do you want to end the session?",
                choices=(
                    ("Yes, end the session", on_decline),
                    ("Back to the consent text", back),
                ),
            )

        def back() -> None:
            self.show_consent(text, on_agree=on_agree, agree=agree, on_decline=on_decline)

        return self.show_message(
            "Consent",
            text,
            choices=((agree, on_agree), (DECLINE, confirm)),
        )

    def show_questions(
        self,
        heading: str,
        intro: str,
        items: Sequence[Item],
        *,
        progress: str | None,
        on_submit: Callable[[dict[str, object]], None],
    ) -> int:
        """Each item's prompt (a Likert item's with its anchors) and its field
        (:mod:`study.server.answer_fields`); Continue needs every required answer, valid, and
        submits them once: viser runs clicks in a thread pool, and a second click read with
        the first would otherwise submit a copy that answers the next screen's item of the
        same id (a failed submit redraws the screen, with a Continue of its own)."""
        with self._lock:
            screen = self._new_screen("questions:" + heading)
            self._header(progress)
            self._md(f"**{heading}**\n\n{intro}")
            answers: dict[str, object] = {}
            invalid: set[str] = set()
            submit = None

            def complete() -> bool:
                return not invalid and all(i.id in answers or i.optional for i in items)

            def report(item_id: str, value: object, valid: bool) -> None:
                answers.pop(item_id, None)
                invalid.discard(item_id)
                if value is not None:
                    answers[item_id] = value
                if not valid:
                    invalid.add(item_id)
                if submit is not None:
                    submit.disabled = not complete()

            for item in items:
                prompt = f"**{item.prompt}**"
                if isinstance(item, LikertItem):
                    prompt += f"\n\n{item.anchor_text()}"
                self._md(prompt)
                add_answer_field(self, item, current=lambda: self._current(screen), report=report)
            submit = self._button("Continue", disabled=not complete())
            claimed = threading.Lock()  # the first complete submit on this screen wins, once

            @submit.on_click
            def _(_: object) -> None:
                if not self._current(screen):
                    return
                if not complete():
                    self.reject("not every item has an answer")
                    return
                if not claimed.acquire(blocking=False):
                    return  # a second click of the same screen: its answers are on their way
                submit.disabled = True
                on_submit({i.id: answers.get(i.id) for i in items})

            return screen

    def show_trial(
        self,
        *,
        heading: str,
        instruction: str,
        progress: str | None,
        on_grasp: Callable[[], None],
        on_view: Callable[[], None],
        time_left_s: float | None = None,
    ) -> int:
        """The trial screen: the instruction, the time left (``time_left_s`` now, then
        :meth:`set_time_left`), the view from above (its frames come through :meth:`show_inset`),
        a grasp and a view button, and the key help."""
        with self._lock:
            screen = self._new_screen("trial:" + heading)
            self._header(progress)
            self._md(f"**{heading}**\n\n{instruction}")
            # the render loop keeps it current (the run may start a moment after this screen)
            self._clock = self._md(clock_text(time_left_s) if time_left_s is not None else " ")
            w, h = INSET_SIZE
            self._inset = self.client.gui.add_image(
                np.full((h, w, 3), 235, np.uint8), format="jpeg", jpeg_quality=80
            )
            self._handles.append(self._inset)
            b = self._grasp = self._button(GRASP_LABEL)
            v = self._button("Back to the starting view (V)")
            self._md(KEY_HELP)

            @b.on_click
            def _(_: object) -> None:
                if self._current(screen):
                    on_grasp()

            @v.on_click
            def _(_: object) -> None:
                on_view()

            return screen

    def set_time_left(self, seconds: float) -> None:
        """Update the trial screen's countdown (sends only when the shown text changes)."""
        text = clock_text(seconds)
        with self._lock:
            if self._clock is not None and text != self._clock_text:
                self._clock_text = text
                self._clock.content = check_text(text, words=self.words)

    def show_gripper_closed(self, closed: bool) -> None:
        """The trial screen's grasp button: :data:`GRIPPER_CLOSED_LABEL` and greyed while the
        gripper is ``closed``, else :data:`GRASP_LABEL` (sends only on a change)."""
        with self._lock:
            b = self._grasp
            if b is None or closed == self._grasp_closed:
                return
            self._grasp_closed = closed
            b.label = check_text(GRIPPER_CLOSED_LABEL if closed else GRASP_LABEL, words=self.words)
            b.disabled = closed

    @property
    def shows_inset(self) -> bool:
        return self._inset is not None

    def show_inset(self, jpeg: bytes) -> None:
        """Show one frame of the view from above: JPEG bytes, encoded and checked for condition
        words by :mod:`study.server.inset` (viser would otherwise re-encode the array)."""
        with self._lock:
            if self._inset is not None:
                viser_door.set_image_bytes(self._inset, jpeg)

    # -- teleoperation (the handle: ``study.server.page_handle``) ----------------------------
    @property
    def dragging(self) -> bool:
        """True while the participant holds the handle with the mouse."""
        return self.handle.dragging

    def add_gizmo(
        self,
        position: np.ndarray,
        *,
        on_target: Callable[[np.ndarray], None],
        on_release: Callable[[], None] | None = None,
    ) -> viser.TransformControlsHandle:
        """The handle over the target ``position`` (:meth:`TeleopHandle.add`)."""
        return self.handle.add(position, on_target=on_target, on_release=on_release)

    def move_gizmo(self, position: np.ndarray) -> None:
        """Put the handle over the target ``position``."""
        self.handle.move(position)

    def show_gizmo(self, visible: bool) -> None:
        self.handle.show(visible)

    def remove_gizmo(self) -> None:
        self.handle.remove()


def clock_text(seconds: float) -> str:
    """``"Time left: **1:05**"`` for 65 s (rounded up: 0:00 only when the time is up)."""
    s = max(0, math.ceil(seconds - 1e-9))
    return f"Time left: **{s // 60}:{s % 60:02d}**"

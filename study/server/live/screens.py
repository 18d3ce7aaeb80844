"""How the session's blind ``Screen`` is shown on the participant's tab.

One function of the screen and the live session's own state (a held control fault, who paused,
the last run's outcome sentence): which page to build and which of the live session's handlers
its buttons call. It decides nothing about the session: the handlers do that.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

from study.protocol.model import Texts
from study.server.live.texts import (
    REDIRECT_DELAY_S,
    RUN_FINISHED,
    TAB_LOST_TEXT,
    WAIT_TEXT,
    WAITING_TEXT,
    end_screen,
)
from study.server.participant_page import KEYS_BEFORE_START, ParticipantPage
from study.server.recruitment import redirect_script
from study.session import PauseCause, Screen


class PageHandlers(Protocol):
    """What the page's buttons and keys call (``LiveSession`` implements it)."""

    def agree(self) -> None: ...
    def decline(self) -> None: ...
    def start_trial(self) -> None: ...
    def answer(self, answers: Mapping[str, object]) -> None: ...
    def finish(self) -> None: ...
    def continue_after_tab_lost(self) -> None: ...
    def seen_outcome(self) -> None: ...
    def grasp(self) -> None: ...
    def reframe(self) -> None: ...
    def preview(self, page: ParticipantPage) -> None: ...
    def time_left(self) -> float | None: ...


def show_screen(
    page: ParticipantPage,
    screen: Screen,
    *,
    fault: bool,
    paused_by: PauseCause | None,
    outcome: str | None,
    agree_label: str,
    handlers: PageHandlers,
    status: str = "",
    texts: Texts | None = None,
) -> None:
    """Build ``screen`` on ``page`` (see module docstring): a held fault, a pause or the last
    run's outcome first, else the screen of the session's phase."""
    # "Practice run 2 of 3", "Run 5 of 8"; none before the first run (the questions about
    # the participant)
    progress: str | None = screen.progress.text or None
    if progress is not None and (progress in screen.title or progress in screen.text):
        progress = None  # said once is enough
    interrupted = _show_interruption(
        page,
        screen,
        fault=fault,
        paused_by=paused_by,
        outcome=outcome,
        progress=progress,
        handlers=handlers,
    )
    if not interrupted:
        _show_phase(
            page,
            screen,
            progress=progress,
            agree_label=agree_label,
            handlers=handlers,
            status=status,
            texts=texts,
        )


def _show_interruption(
    page: ParticipantPage,
    screen: Screen,
    *,
    fault: bool,
    paused_by: PauseCause | None,
    outcome: str | None,
    progress: str | None,
    handlers: PageHandlers,
) -> bool:
    """Show a held fault, a pause or the last run's outcome; False when there is none."""
    if fault:
        page.show_message("Please wait", WAIT_TEXT, progress=progress)
    elif screen.paused and paused_by == "tab_lost":
        page.show_message(
            "Paused",
            TAB_LOST_TEXT,
            progress=progress,
            button="Continue",
            on_button=handlers.continue_after_tab_lost,
        )
    elif screen.paused:
        page.show_message("Please wait", screen.text or WAIT_TEXT, progress=progress)
    elif outcome is not None and screen.phase != "running":
        page.show_message(
            RUN_FINISHED,
            outcome,
            progress=None,  # the session already counts the next run: no number is right here
            button="Continue",
            on_button=handlers.seen_outcome,
        )
    else:
        return False
    return True


def _show_phase(
    page: ParticipantPage,
    screen: Screen,
    *,
    progress: str | None,
    agree_label: str,
    handlers: PageHandlers,
    status: str,
    texts: Texts | None,
) -> None:
    """The screen of the session's phase."""
    title, text = screen.title, screen.text
    if screen.phase == "consent":
        page.show_consent(
            text, on_agree=handlers.agree, agree=agree_label, on_decline=handlers.decline
        )
    elif screen.phase == "ready":  # the keys too: known before the run's clock starts
        handlers.preview(page)
        page.show_message(
            title,
            f"{text}\n\n{KEYS_BEFORE_START}",
            progress=progress,
            button="Start",
            on_button=handlers.start_trial,
        )
    elif screen.phase == "running":
        page.show_trial(
            heading=title,
            instruction=text,
            progress=progress,
            on_grasp=handlers.grasp,
            on_view=handlers.reframe,
            time_left_s=handlers.time_left(),
        )
    elif screen.phase == "questions":
        page.show_questions(
            title, text, list(screen.items), progress=progress, on_submit=handlers.answer
        )
    elif screen.phase == "debrief":
        page.show_message(title, text, progress=None, button="Finish", on_button=handlers.finish)
    elif screen.phase == "done" and texts is not None:
        show_end(page, status, texts)
    elif screen.phase == "done":
        page.show_message(title or "Done", (text + "\n\n" if text else "") + "Thank you.")
    else:  # waiting: the protocol's welcome, and that the experimenter starts the session
        page.show_message(title, (text + "\n\n" if text else "") + WAITING_TEXT)


def show_end(page: ParticipantPage, status: str, texts: Texts) -> None:
    """The end of the session (``texts.end_screen``): after a completed session with a
    ``redirect_url``, the page goes back to the recruitment site by itself after
    ``REDIRECT_DELAY_S`` seconds, or at once on Continue."""
    title, text, redirect = end_screen(status, texts)
    if redirect is None:
        page.show_message(title, text)
        return
    page.show_message(
        title, text, button="Continue", on_button=lambda: page.run_script(redirect_script(redirect))
    )
    page.run_script(redirect_script(redirect, delay_ms=REDIRECT_DELAY_S * 1000))

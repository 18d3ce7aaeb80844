"""A participant's whole session in headless Chromium, checked against the store.

One walk through every kind of screen (waiting, consent, ready, trial, items, preference,
debrief, done) with a protocol shortened to one practice run and 15 s trials: the gizmo is
dragged with the mouse and the arm follows in the stored samples, keys nudge the target, the
grasp button is logged, answers land in the ratings table, a reload mid-trial pauses and
resumes the trial (paused time excluded), a second tab is refused, and no condition name
reaches the page or its websocket. Screenshots of each phase go to a temporary folder, or to
tests/browser/screenshots (linked from the README) with UPDATE_SCREENSHOTS=1.
"""

from __future__ import annotations

import io
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import expect

from tests.browser.harness import (
    FrameLog,
    RunningServer,
    drag,
    project,
    start_server,
    wait_until,
)

pytestmark = pytest.mark.browser

TIME_LIMIT_S = 15.0
EXPERIMENTER_ONLY = ("Experimenter console", "Enrol", "Withdraw", "Goal probabilities", "alpha")


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(tmp_path, time_limit_s=TIME_LIMIT_S, training_runs=1)
    try:
        yield rs
    finally:
        rs.stop()


AGREE = "I have read this and agree to take part"


def _connect(page: Any, url: str) -> None:
    """Open ``url`` and wait for viser's "Connected". A page still not connected after 30 s is
    reloaded once, as a person would; what it showed is printed (seen about once in 850 tests
    on a loaded machine; not yet explained), and a second failure fails the test with it."""
    page.goto(url)
    try:
        page.get_by_text("Connected").first.wait_for(timeout=30_000)
        return
    except Exception:
        shown = page.inner_text("body")[:300]
        print(f"not connected after 30 s, reloading; the page showed: {shown!r}")
    page.reload()
    try:
        page.get_by_text("Connected").first.wait_for(timeout=30_000)
    except Exception as exc:
        shown = page.inner_text("body")[:300]
        raise AssertionError(f"not connected after a reload; the page showed: {shown!r}") from exc


def text_input(page: Any, label: str) -> Any:
    """viser's text input next to ``label`` (its <label for> does not name the input)."""
    return page.locator(
        f"xpath=//label[text()='{label}']/ancestor::div[contains(@class, 'mantine-Flex-root')][1]"
        "//input"
    )


def join(page: Any, code: str, *, then: str | None = AGREE) -> None:
    """Type the join code as a participant would and wait for the button ``then``."""
    page.get_by_text("Please type the join code").wait_for()
    field = text_input(page, "Join code")
    field.click()
    field.fill("")
    page.keyboard.type(code.lower(), delay=40)  # typed into the field: no key reaches the arm
    page.get_by_role("button", name="Join").click()
    if then is not None:
        page.get_by_role("button", name=then).wait_for()


def hold(page: Any, key: str, seconds: float, *, repeat_hz: float = 30.0) -> None:
    """Hold ``key`` for ``seconds`` with auto-repeat, as a keyboard does."""
    page.keyboard.down(key)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        page.wait_for_timeout(1000 / repeat_hz)
        page.keyboard.down(key)  # a repeat: KeyboardEvent.repeat is true
    page.keyboard.up(key)


def _shot(page: Any, folder: Path, name: str, *, colors: int = 96) -> None:
    """Save a small screenshot for the README (PNG with a ``colors`` palette). The viewer's
    own notices (software WebGL) are the page's to hide (``study.server.page_head``): a
    screenshot shows what the participant sees. 96 colours merge the box's orange with the
    table's in the view from above (the box looks hollow): 256 keep it."""
    page.wait_for_timeout(300)
    t = time.monotonic()
    png = page.screenshot()
    print(f"screenshot {name}: {time.monotonic() - t:.1f} s")
    image = Image.open(io.BytesIO(png)).convert("RGB")
    image.quantize(colors=colors, method=Image.Quantize.MEDIANCUT).save(
        folder / f"{name}.png", optimize=True
    )


def _settle(page: Any, *, rounds: int = 2) -> None:
    """Wait until the browser draws frames quickly again (each screenshot waits for a frame)."""
    for _ in range(rounds):
        t = time.monotonic()
        page.screenshot()
        print(f"settle frame: {time.monotonic() - t:.1f} s")


def _answer_all(page: Any, n_items: int, value: int) -> None:
    """Click ``value`` on each of the ``n_items`` rows, checking Continue waits for all."""
    cont = page.get_by_role("button", name="Continue")
    expect(cont).to_be_disabled()
    for k in range(n_items):
        page.get_by_role("button", name=str(value), exact=True).first.click()
        page.get_by_text(f"Your answer: {value}").nth(k).wait_for()
    expect(page.get_by_role("button", name=f"[{value}]", exact=True)).to_have_count(n_items)
    expect(cont).to_be_enabled()
    cont.click()


def _trial_rows(rs: RunningServer) -> list[Any]:
    return rs.store.trials()


def _events(rs: RunningServer) -> list[Any]:
    return rs.store.events()


def _without_client_warning(text: str) -> str:
    """The page text minus the viser client's own software-rendering notice ("... check that
    hardware acceleration is enabled ..."), which the browser bundle shows by itself when WebGL
    runs in software; the server never sends it (the websocket check below covers that)."""
    lines = text.splitlines()
    return "\n".join(ln for ln in lines if "WebGL" not in ln and "hardware acceleration" not in ln)


def _texts_ok(texts: list[str], words: tuple[str, ...]) -> None:
    joined = "\n".join(texts).lower()
    for word in words:
        assert word not in joined, f"condition word {word!r} reached the participant"


def test_participant_session_end_to_end(study: RunningServer, context: Any, screenshots: Path):
    srv = study.server
    page = context.new_page()
    frames = FrameLog().attach(page)
    seen: list[str] = []

    def text_now() -> str:
        body = page.inner_text("body")
        seen.append(_without_client_warning(body))
        return body

    # The join screen, then the code; the session waits for the experimenter's start.
    _connect(page, study.url)
    code = srv.enrol("P01")
    page.get_by_text("Please type the join code").wait_for()
    assert page.title() == "Robot arm study"
    for chrome in ("adjustments", "share", "list-search"):  # viser's settings, share, commands
        assert not page.locator(f"svg.tabler-icon-{chrome}").first.is_visible()
    join(page, code, then=None)
    page.get_by_text("Please wait").first.wait_for()
    _shot(page, screenshots, "01-waiting")
    text_now()
    srv.act(code, "start")

    # Consent, with the protocol's own button.
    page.get_by_role("button", name=AGREE).wait_for()
    _shot(page, screenshots, "02-consent")
    text_now()
    page.get_by_role("button", name=AGREE).click()

    # Practice run: ready, then the trial screen with the scene and the gizmo.
    page.get_by_role("button", name="Start").wait_for()
    body = text_now()
    assert body.count("Trial 1 of") == 1
    _shot(page, screenshots, "03-ready")
    _settle(page)  # the scene's first draw is slow in software WebGL
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    live = srv.session(code)
    assert wait_until(lambda: live.scene_view is not None and live.scene_view.frames_sent >= 1)
    text_now()

    run = live.run
    start = np.array(run.trial.user_target, float)
    cam = live.page.client.camera
    grab = project(cam, start + np.array([0.0, 0.0, 0.2]))
    t_drag = time.monotonic()
    drag(page, grab, (grab[0], grab[1] - 40), steps=5)
    print(f"drag took {time.monotonic() - t_drag:.1f} s; trial time {run.trial.t:.1f} s")
    assert wait_until(lambda: run.trial.user_target[2] > start[2] + 0.03, timeout=5)
    # Keyboard: holding F lowers the target while it is held (0.1 m/s).
    before = float(run.trial.user_target[2])
    hold(page, "f", 0.6)
    print(f"key held until trial time {run.trial.t:.1f} s")
    assert wait_until(lambda: run.trial.user_target[2] < before - 0.03, timeout=5)
    page.get_by_role("button", name="Close the gripper (G)").click()
    trial_id = run.trial_id
    _shot(page, screenshots, "04-trial")

    # How the run ended (a neutral sentence), then three 7-point rows with anchors.
    page.get_by_text("Run finished").wait_for(timeout=30_000)
    assert "Time is up." in text_now()
    assert "Trial 2 of" not in text_now()  # the run that finished was trial 1, not the next
    _shot(page, screenshots, "04b-outcome")
    page.get_by_role("button", name="Continue").click()
    page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
    body = text_now()
    assert "Not at all helpful" in body and "Extremely helpful" in body
    _shot(page, screenshots, "05-questions")
    samples = study.store.samples(trial_id)
    assert len(samples) > 0.9 * TIME_LIMIT_S * 100
    assert samples.target_z.max() > start[2] + 0.05  # the gizmo drag
    assert samples.ee_z.max() > start[2] + 0.04  # ... and the arm followed
    events = [e for evs in samples.events for e in json.loads(evs)]
    assert "grasp_requested" in events
    _answer_all(page, 3, 5)
    assert wait_until(lambda: len(study.store.ratings()) == 3)  # Continue's write lands
    ratings = study.store.ratings()
    assert sorted(r.item for r in ratings) == ["helpful", "matched", "teammate"]
    assert {r.value for r in ratings} == {5} and {r.phase for r in ratings} == {"training"}

    # First task run: reload mid-trial -> paused (an event), Continue resumes.
    page.get_by_role("button", name="Start").wait_for()
    assert text_now().count("Trial 2 of") == 1
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    page.wait_for_timeout(1500)
    page.reload()
    page.get_by_text("Connected").first.wait_for(timeout=30_000)
    page.get_by_role("button", name="Continue").wait_for()  # the tab kept its code
    paused_at = time.monotonic()
    text_now()
    _shot(page, screenshots, "06-paused-after-reload")
    kinds = [e.kind for e in _events(study)]
    assert "participant_disconnected" in kinds and "pause" in kinds

    # A second tab cannot take the session over, even with the code.
    intruder = context.new_page()
    intruder_frames = FrameLog().attach(intruder)
    _connect(intruder, study.url)
    join(intruder, code, then=None)
    intruder.get_by_text("That code did not work").wait_for()
    _shot(intruder, screenshots, "07-second-tab-refused")
    intruder.close()
    assert "second_tab_refused" in [e.kind for e in _events(study)]
    assert live.page is not None and live.page.client.client_id != -1

    page.wait_for_timeout(1000)
    page.get_by_role("button", name="Continue").click()
    pause_s = time.monotonic() - paused_at
    page.get_by_text("Run finished").wait_for(timeout=30_000)
    page.get_by_role("button", name="Continue").click()
    page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
    task_trial = next(t for t in _trial_rows(study) if t.phase == "task")
    assert task_trial.status == "completed"
    assert task_trial.duration_s == pytest.approx(TIME_LIMIT_S, abs=0.05)  # pause excluded
    kinds = [e.kind for e in _events(study)]
    assert "resume" in kinds and pause_s > 2.0
    _answer_all(page, 3, 6)

    # Console screenshot while the second run is live (plots of alpha, confidence, P(goal)).
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    console = context.new_page()
    console.set_viewport_size({"width": 1100, "height": 1250})
    _connect(console, study.console_url)
    srv.console.select(code)  # as choosing it in the session list does
    console.get_by_text("Goal probabilities").wait_for(timeout=15_000)
    console.wait_for_timeout(1500)
    _shot(console, screenshots, "10-experimenter-console")
    console.close()

    # After-run items, then the preference item naming "first run" and "second run".
    page.get_by_text("Run finished").wait_for(timeout=30_000)
    page.get_by_role("button", name="Continue").click()
    page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
    _answer_all(page, 3, 3)
    page.get_by_text("Which of the two runs of this task did you prefer?").wait_for()
    body = text_now()
    assert "first run" in body and "second run" in body
    _shot(page, screenshots, "08-preference")
    _answer_all(page, 1, 2)
    assert wait_until(lambda: any(r.item == "preference" for r in study.store.ratings()))
    prefs = [r for r in study.store.ratings() if r.item == "preference"]
    assert [p.value for p in prefs] == [2]

    # The experimenter skips the other tasks; debrief, then done.
    for _ in range(40):
        if live.session.phase() == "debrief":
            break
        srv.act(code, "skip", reason="test: on to the next step")
    page.get_by_role("button", name="Finish").wait_for()
    _shot(page, screenshots, "09-debrief")
    text_now()
    page.get_by_role("button", name="Finish").click()
    page.get_by_text("Done").first.wait_for()
    assert study.store.session("P01").status == "completed"

    # Blinding: page text, every websocket message, and the guard itself.
    words = study.protocol.condition_words  # (every shipped protocol: tests/browser/test_blinding)
    _texts_ok(seen, words)
    strings = frames.strings() + intruder_frames.strings()
    assert len(strings) > 100
    _texts_ok(strings, words)
    raw = frames.raw_bytes() + intruder_frames.raw_bytes()  # incl. mesh (GLB) buffers
    for word in words:
        assert word.encode() not in raw, word
    assert srv.guard.violations == []
    for marker in EXPERIMENTER_ONLY:
        assert not any(marker in s for s in strings), marker

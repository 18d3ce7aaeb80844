"""A participant's whole session in headless Chromium, checked against the store.

One walk through every kind of screen (waiting, consent, ready, trial, items, preference,
debrief, done) with a protocol shortened to one 15 s practice run and 10 s task runs: the gizmo is
dragged with the mouse and the arm follows in the stored samples, keys nudge the target, the
grasp button is logged, answers land in the ratings table, a reload mid-trial pauses and
resumes the trial (paused time excluded), a second tab is refused, and no condition name
reaches the page or its websocket. Screenshots of each phase go to a temporary folder, or to
tests/browser/screenshots (linked from the README) with UPDATE_SCREENSHOTS=1.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.browser.harness import (
    TEST_WEBGL,
    FrameLog,
    RunningServer,
    drag_until,
    start_server,
    wait_until,
)
from tests.browser.page import (
    AGREE,
    answer_all,
    connect_page,
    hold,
    join,
    page_pixel,
    screenshot,
    settle_frames,
    wait_camera_still,
    wait_connected,
    without_client_warning,
)
from tests.protocol_copies import short_practice

pytestmark = pytest.mark.browser

PRACTICE_S = 15.0
"""The practice run: a drag and a held key within it on a loaded machine (a drag planned for
3 s has taken 12 s there)."""
TASK_S = 10.0
"""The task runs, waited out: a reload early in the first, the console opened in the second."""
EXPERIMENTER_ONLY = ("Experimenter console", "Enrol", "Withdraw", "Goal probabilities", "alpha")


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(
        tmp_path,
        time_limit_s=TASK_S,
        training_runs=1,
        edit=lambda p: short_practice(p, seconds=PRACTICE_S),
    )
    try:
        yield rs
    finally:
        rs.stop()


def _trial_rows(rs: RunningServer) -> list[Any]:
    return rs.store.trials()


def _events(rs: RunningServer) -> list[Any]:
    return rs.store.events()


def _texts_ok(texts: list[str], words: tuple[str, ...]) -> None:
    joined = "\n".join(texts).lower()
    for word in words:
        assert word not in joined, f"condition word {word!r} reached the participant"


CANVAS_JS = """() => {
  const area = (c) => c.clientWidth * c.clientHeight;
  const view = [...document.querySelectorAll("canvas")].sort((a, b) => area(b) - area(a))[0];
  const gl = view.getContext("webgl2");  // the 3-D view's own context (three.js: WebGL 2)
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  return {antialias: gl.getContextAttributes().antialias,
          renderer: String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER))};
}"""
"""The 3-D view's WebGL context (the page's largest canvas): whether it multisamples, and what
draws it."""


def test_participant_session_end_to_end(study: RunningServer, context: Any, screenshots: Path):
    srv = study.server
    page = context.new_page()
    frames = FrameLog().attach(page)
    seen: list[str] = []

    def text_now() -> str:
        body = page.inner_text("body")
        seen.append(without_client_warning(body))
        return body

    # The join screen, then the code; the session waits for the experimenter's start.
    connect_page(page, study.url)
    code = srv.enrol("P01")
    page.get_by_text("Please type the join code").wait_for()
    assert page.title() == "Robot arm study"
    for chrome in ("adjustments", "share", "list-search"):  # viser's settings, share, commands
        assert not page.locator(f"svg.tabler-icon-{chrome}").first.is_visible()
    join(page, code, then=None)
    page.get_by_text("Please wait").first.wait_for()
    screenshot(page, screenshots, "01-waiting")
    text_now()
    srv.act(code, "start")

    # Consent, with the protocol's own button.
    page.get_by_role("button", name=AGREE).wait_for()
    screenshot(page, screenshots, "02-consent")
    text_now()
    page.get_by_role("button", name=AGREE).click()

    # Practice run: ready, then the trial screen with the scene and the gizmo.
    page.get_by_role("button", name="Start").wait_for()
    body = text_now()
    # counted as the consent counts: the practice runs apart from the main part's runs, once
    assert body.count("Practice run 1 of 1") == 1 and "Trial" not in body
    assert "W/S (away / back)" in body  # the keys, before Start
    screenshot(page, screenshots, "03-ready")
    settle_frames(page)  # the scene's first draw is slow in software WebGL
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    live = srv.session(code)
    assert wait_until(lambda: live.scene_view is not None and live.scene_view.frames_sent >= 1)
    text_now()
    # the tests' Chromium draws WebGL on the CPU (llvmpipe, or SwiftShader as a laptop without a
    # GPU does): the 3-D view runs without multisampling
    # (study.server.software_webgl: +37 % frames/s), and says what drew it
    drawn = page.evaluate(CANVAS_JS)
    assert TEST_WEBGL in drawn["renderer"].lower() and drawn["antialias"] is False, drawn

    run = live.run
    start = np.array(run.trial.user_target, float)
    cam = live.page.client.camera
    wait_camera_still(live)
    grab = tuple(page_pixel(page, cam, start + np.array([0.0, 0.0, 0.2])))
    t_drag = time.monotonic()
    lifted = drag_until(
        page,
        grab,
        (grab[0], grab[1] - 40),
        lambda: run.trial.user_target[2] > start[2] + 0.03,
        steps=5,
        timeout=5,
    )
    print(f"drag took {time.monotonic() - t_drag:.1f} s; trial time {run.trial.t:.1f} s")
    assert lifted, "dragging the handle's up arrow did not raise the target"
    # Keyboard: holding F lowers the target while it is held (0.1 m/s).
    before = float(run.trial.user_target[2])
    hold(page, "f", 0.6)
    print(f"key held until trial time {run.trial.t:.1f} s")
    assert wait_until(lambda: run.trial.user_target[2] < before - 0.03, timeout=5)
    page.get_by_role("button", name="Close the gripper (G)").click()
    trial_id = run.trial_id
    screenshot(page, screenshots, "04-trial")

    # How the run ended (a neutral sentence), then three 7-point rows with anchors.
    page.get_by_text("Run finished").wait_for(timeout=30_000)
    assert "Time is up." in text_now()
    assert "Run 1 of" not in text_now()  # the run that finished was the practice, not the next
    screenshot(page, screenshots, "04b-outcome")
    page.get_by_role("button", name="Continue").click()
    page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
    body = text_now()
    assert "Not at all helpful" in body and "Extremely helpful" in body
    screenshot(page, screenshots, "05-questions")
    samples = study.store.samples(trial_id)
    assert len(samples) > 0.9 * PRACTICE_S * 100
    assert samples.target_z.max() > start[2] + 0.05  # the gizmo drag
    assert samples.ee_z.max() > start[2] + 0.04  # ... and the arm followed
    events = [e for evs in samples.events for e in json.loads(evs)]
    assert "grasp_requested" in events
    answer_all(page, 3, 5)
    assert wait_until(lambda: len(study.store.ratings()) == 3)  # Continue's write lands
    ratings = study.store.ratings()
    assert sorted(r.item for r in ratings) == ["helpful", "matched", "teammate"]
    assert {r.value for r in ratings} == {5} and {r.phase for r in ratings} == {"training"}

    # First task run: reload mid-trial -> paused (an event), Continue resumes.
    page.get_by_role("button", name="Start").wait_for()
    assert text_now().count("Run 1 of 8") == 1
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    page.wait_for_timeout(1500)
    page.reload()
    wait_connected(page)
    page.get_by_role("button", name="Continue").wait_for()  # the tab kept its code
    paused_at = time.monotonic()
    text_now()
    screenshot(page, screenshots, "06-paused-after-reload")
    kinds = [e.kind for e in _events(study)]
    assert "participant_disconnected" in kinds and "pause" in kinds

    # A second tab cannot take the session over, even with the code.
    intruder = context.new_page()
    intruder_frames = FrameLog().attach(intruder)
    connect_page(intruder, study.url)
    join(intruder, code, then=None)
    intruder.get_by_text("That code did not work").wait_for()
    screenshot(intruder, screenshots, "07-second-tab-refused")
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
    assert task_trial.duration_s == pytest.approx(TASK_S, abs=0.05)  # pause excluded
    kinds = [e.kind for e in _events(study)]
    assert "resume" in kinds and pause_s > 2.0
    answer_all(page, 3, 6)

    # Console screenshot while the second run is live (plots of alpha, confidence, P(goal)).
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    console = context.new_page()
    console.set_viewport_size({"width": 1100, "height": 1250})
    connect_page(console, study.console_url)
    srv.console.select(code)  # as choosing it in the session list does
    console.get_by_text("Goal probabilities").wait_for(timeout=15_000)
    console.wait_for_timeout(1500)
    screenshot(console, screenshots, "10-experimenter-console")
    console.close()

    # After-run items, then the preference item naming "first run" and "second run".
    page.get_by_text("Run finished").wait_for(timeout=30_000)
    page.get_by_role("button", name="Continue").click()
    page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
    answer_all(page, 3, 3)
    page.get_by_text("Which of these two runs did you prefer?").wait_for()
    body = text_now()
    assert "first run" in body and "second run" in body
    assert "run 1 and run 2" in body and "this task" not in body  # the runs as the page counted
    screenshot(page, screenshots, "08-preference")
    answer_all(page, 1, 2)
    assert wait_until(lambda: any(r.item == "preference" for r in study.store.ratings()))
    prefs = [r for r in study.store.ratings() if r.item == "preference"]
    assert [p.value for p in prefs] == [2]

    # The experimenter skips the other tasks; debrief, then done.
    for _ in range(40):
        if live.session.phase() == "debrief":
            break
        srv.act(code, "skip", reason="test: on to the next step")
    page.get_by_role("button", name="Finish").wait_for()
    screenshot(page, screenshots, "09-debrief")
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

"""The robot's intent on the participant page: a ring around the predicted object, or nothing.

protocols/intent.toml (shortened: one practice run of 2 s, 8 s task runs) gives design row 0 the
Easy&Right task first in mode ``aggressive`` (intent not shown), then in ``aggressive_shown``
(``intent = "goal"``). A participant steers toward the box with held keys in both runs: with
the display off the page never receives a ring node; with it on, the browser's scene tree holds
a visible ring around the object the robot predicts (the box: the Right task's oracle), its
opacity following the robot's confidence. No factor level, task or mode name reaches the page or
its websocket, and the screenshot of the shown run goes with the others.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from study.server.intent_cue import OPACITY_MAX, RING_COLOR, RING_NODE
from tests.browser.harness import FrameLog, RunningServer, start_server, wait_until
from tests.browser.page import (
    AGREE,
    answer_all,
    connect_page,
    hold,
    join,
    screenshot,
    settle_frames,
)
from tests.protocol_copies import short_practice

pytestmark = pytest.mark.browser

INTENT = Path(__file__).resolve().parents[2] / "protocols" / "intent.toml"
PRACTICE_S = 2.0
"""The practice run is only waited out (no ring in it)."""
RING_JS = """(name) => {
  const node = window.__viserSceneTree.getState()[name];
  if (!node) return null;
  const p = node.message.props;
  const pose = window.__viserMutable.nodePoseData[name];
  return {visible: node.visibility ?? null, position: pose ? pose.position : null,
          opacity: p.opacity, color: p.color, scale: p.scale};
}"""


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(
        tmp_path,
        time_limit_s=8.0,
        training_runs=1,
        source=INTENT,
        edit=lambda p: short_practice(p, seconds=PRACTICE_S),
    )
    try:
        yield rs
    finally:
        rs.stop()


def _ring(page: Any) -> dict[str, Any] | None:
    return page.evaluate(RING_JS, RING_NODE)


def _next_run(page: Any, live: Any) -> Any:
    """From the ready screen: start the run, wait for its first frames, return the run."""
    page.get_by_role("button", name="Start").wait_for()
    settle_frames(page)
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    assert wait_until(lambda: live.run is not None and not live.run.over)
    assert wait_until(lambda: live.scene_view is not None and live.scene_view.frames_sent >= 1)
    return live.run


def _finish_run(page: Any) -> None:
    """Wait out the run, continue, answer the three items."""
    page.get_by_text("Run finished").wait_for(timeout=30_000)
    page.get_by_role("button", name="Continue").click()
    page.get_by_text("Your answer: none yet").first.wait_for(timeout=30_000)
    answer_all(page, 3, 4)


def test_intent_ring_shown_only_in_the_mode_that_shows_it(
    study: RunningServer, context: Any, screenshots: Path
) -> None:
    srv = study.server
    page = context.new_page()
    frames = FrameLog().attach(page)
    connect_page(page, study.url)
    code = srv.enrol("P01")
    srv.act(code, "start")
    join(page, code)
    page.get_by_role("button", name=AGREE).click()
    live = srv.session(code)

    # Practice (unassisted): no ring.
    run = _next_run(page, live)
    assert run.config.task == "training" and live.scene_view.intent is None
    _finish_run(page)

    # First task run, mode "aggressive": steer toward the box; no ring node ever exists.
    run = _next_run(page, live)
    assert (run.config.task, run.config.mode) == ("easy-right", "aggressive")
    hold(page, "w", 1.0)
    page.wait_for_timeout(1000)
    assert live.scene_view.intent is None
    assert _ring(page) is None
    assert not any(m.get("name") == RING_NODE for m in frames.messages())
    _finish_run(page)

    # Second run of the task, mode "aggressive_shown": the ring around the predicted box.
    run = _next_run(page, live)
    assert (run.config.task, run.config.mode) == ("easy-right", "aggressive_shown")
    hold(page, "w", 1.0)
    cue = live.scene_view.intent
    assert cue is not None
    target = run.trial.scene.target_index
    assert wait_until(lambda: cue.visible_goal == target, timeout=10)
    assert wait_until(lambda: (_ring(page) or {}).get("visible") is True, timeout=15)
    ring = _ring(page)
    box = run.trial.sim.data.xpos[run.trial.scene.object_body_ids[target]]
    assert np.allclose(ring["position"][:2], box[:2], atol=0.01), (ring, box)
    assert 0.2 * OPACITY_MAX - 1e-6 <= ring["opacity"] <= OPACITY_MAX + 1e-6
    assert tuple(ring["color"]) == RING_COLOR
    radius = ring["scale"][0]
    assert 0.05 < radius < 0.08  # a band around the box's 3.5 cm footprint, not a dot
    screenshot(page, screenshots, "06-intent-ring")
    _finish_run(page)

    # Blinding: no factor level, task or mode name on the page or in any websocket frame.
    words = set(study.protocol.condition_words) | set(study.protocol.task_names)
    strings = "\n".join(frames.strings()).lower()
    raw = frames.raw_bytes()
    body = page.inner_text("body").lower()
    for word in words:
        assert word not in strings and word.encode() not in raw and word not in body, word
    assert srv.guard.violations == []

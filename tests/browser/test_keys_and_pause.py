"""Keys held like a person holds them, on every screen, and a pause with keys held.

viser's own client flies its camera on W/A/S/D/Q/E and the arrow keys; the page script keeps
every steering key away from it. Each key is held for 0.5-1.5 s with auto-repeat on the join,
consent, ready, trial and paused screens and the next run's: the camera does not move and the browser
sends no camera update, while on the trial screen W/S, A/D and R/F move the target along
their axes at the key speed. The experimenter pauses while R is held and the participant keeps
typing; nothing of it is applied on resume, the handle is back on the participant's own
target (where they left it, not where the arm is), and the refused
inputs are in the store. A mouse orbit moves the camera, V brings the task view back.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.teleop.keyboard import KEY_SPEED_M_S
from study.server.page_handle import HANDLE_OFFSET_M
from tests.browser.harness import RunningServer, start_server, wait_still, wait_until
from tests.browser.page import AGREE, connect_page, hold, join, screenshot, settle_frames

pytestmark = pytest.mark.browser

CAMERA_KEYS = ("w", "a", "s", "d", "q", "e", "ArrowUp", "ArrowDown", "ArrowLeft", "ArrowRight")
STEERING = {
    "w": (0, 1.0),
    "s": (0, -1.0),
    "a": (1, 1.0),
    "d": (1, -1.0),
    "r": (2, 1.0),
    "f": (2, -1.0),
}


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(tmp_path, time_limit_s=90.0, training_runs=1)
    try:
        yield rs
    finally:
        rs.stop()


def _camera(page: Any) -> np.ndarray:
    return np.array(page.evaluate("() => window.__viserMutable.camera.position.toArray()"))


class CameraUpdates:
    """Counts the camera updates the server receives from one tab."""

    def __init__(self, client: Any) -> None:
        self.count = 0
        client.camera.on_update(self._seen)

    def _seen(self, _camera: Any) -> None:
        self.count += 1


def _keys_leave_the_camera_alone(page: Any, updates: CameraUpdates | None, *, seconds=0.5):
    # the camera at rest first: a new screen may fly it to its scene's view (a fixed 300 ms
    # was outlasted on a loaded machine: "moved 0.253 m" on the next run's ready screen)
    assert wait_still(lambda: _camera(page), tol=1e-6, still_s=0.5, timeout=15)
    before, n = _camera(page), (updates.count if updates else 0)
    for key in (*CAMERA_KEYS, "g"):
        hold(page, key, seconds)
    page.wait_for_timeout(300)
    moved = float(np.linalg.norm(_camera(page) - before))
    assert moved < 1e-6, f"the camera moved {moved:.3f} m while keys were held"
    if updates is not None:
        assert updates.count == n, "the browser sent camera updates while keys were held"


def test_keys_steer_the_arm_never_the_camera_and_a_pause_freezes_them(
    study: RunningServer, context: Any, screenshots: Path
) -> None:
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    live = srv.session(code)
    page = context.new_page()
    connect_page(page, study.url)
    page.get_by_text("Please type the join code").wait_for()
    _keys_leave_the_camera_alone(page, None, seconds=0.5)  # join screen, nothing bound yet
    join(page, code)
    updates = CameraUpdates(live.page.client)
    _keys_leave_the_camera_alone(page, updates)  # consent
    page.get_by_role("button", name=AGREE).click()
    page.get_by_role("button", name="Start").wait_for()
    settle_frames(page)
    _keys_leave_the_camera_alone(page, updates)  # ready
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    assert wait_until(lambda: live.run is not None and live.scene_view is not None)
    run = live.run
    settle_frames(page)

    # Trial: each steering key moves the target along its axis at the key speed.
    for key, (axis, sign) in STEERING.items():
        before = np.array(run.trial.user_target, float)
        cam = _camera(page)
        n = updates.count
        hold(page, key, 0.8)
        wait_still(lambda: run.trial.user_target, timeout=5)  # the release landed
        moved = np.array(run.trial.user_target, float) - before
        # at least a tenth of 0.8 s at the key speed: a page drawing for two busy lanes once
        # passed its key-down on 0.6 s late (2 cm instead of 8); none at all fails
        assert sign * moved[axis] > 0.1 * 0.8 * KEY_SPEED_M_S, (key, moved)
        assert sign * moved[axis] < 3.0 * 0.8 * KEY_SPEED_M_S, (key, moved)
        others = np.delete(np.abs(moved), axis)
        assert others.max() < 0.01, (key, moved)
        assert float(np.linalg.norm(_camera(page) - cam)) < 1e-6 and updates.count == n
    target = np.array(run.trial.user_target, float)
    for key in ("q", "e", "ArrowUp", "ArrowLeft"):  # camera keys that steer nothing
        hold(page, key, 0.5)
    assert np.allclose(run.trial.user_target, target, atol=1e-6)
    screenshot(page, screenshots, "04c-trial-after-keys")

    # A mouse orbit moves the camera; V brings the task view back.
    task_view = _camera(page)
    page.mouse.move(200, 500)
    page.mouse.down()
    page.mouse.move(330, 470, steps=8)
    page.mouse.up()
    assert wait_until(lambda: float(np.linalg.norm(_camera(page) - task_view)) > 0.05, timeout=10)
    hold(page, "v", 0.2)
    assert wait_until(lambda: float(np.linalg.norm(_camera(page) - task_view)) < 0.01, timeout=10)

    # The experimenter pauses while R is held; the participant keeps typing during the pause.
    page.keyboard.down("r")
    page.wait_for_timeout(400)
    srv.act(code, "pause")
    page.get_by_text("Please wait").first.wait_for()
    screenshot(page, screenshots, "06b-paused-by-experimenter")
    paused_at = np.array(run.trial.user_target, float)
    _keys_leave_the_camera_alone(page, updates, seconds=0.4)  # includes G
    for key in ("w", "r", "r", "r"):
        hold(page, key, 0.3)
    page.keyboard.up("r")
    assert live.page.handle.gizmo is not None and not live.page.handle.gizmo.visible
    srv.act(code, "resume")
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    page.wait_for_timeout(1500)
    after = np.array(run.trial.user_target, float)
    assert float(np.linalg.norm(after - paused_at)) < 0.02, "input from the pause was applied"
    handle = np.array(live.page.handle.gizmo.position) - np.array([0.0, 0.0, HANDLE_OFFSET_M])
    assert float(np.linalg.norm(handle - after)) < 0.02  # the handle is on the target again
    assert live.page.handle.gizmo.visible
    rejected = [e for e in study.store.events() if e.kind == "input_rejected"]
    assert any("while paused" in str(e.detail) for e in rejected)
    events = [e for evs in study.store.samples(run.trial_id).events for e in json.loads(evs)]
    assert "grasp_requested" not in events  # G was pressed only while paused

    # The next screen: keys still leave the camera alone.
    srv.act(code, "skip", reason="test: on to the next step")
    page.get_by_role("button", name="Start").wait_for()
    settle_frames(page)
    _keys_leave_the_camera_alone(page, updates)

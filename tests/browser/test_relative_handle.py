"""The relative input mapping on the page, with the mouse: the handle dragged far below the
table moves the gripper only as far as the reach allows, and on release the handle is back on
the gripper (under the absolute mapping it would stay where it was dropped, 30 cm away)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from study.server.page_handle import HANDLE_OFFSET_M
from tests.browser.harness import drag_until, start_server, wait_until
from tests.browser.page import (
    AGREE,
    canvas_box,
    connect_page,
    join,
    page_pixel,
    screenshot,
    settle_frames,
    wait_camera_still,
)
from tests.protocol_copies import relative_copy

pytestmark = pytest.mark.browser


def test_a_released_handle_returns_to_the_gripper(
    tmp_path: Path, context: Any, screenshots: Path
) -> None:
    study = start_server(
        tmp_path, time_limit_s=60.0, training_runs=1, source=relative_copy(tmp_path)
    )
    try:
        srv = study.server
        assert study.protocol.control.input_mapping == "relative"
        page = context.new_page()
        connect_page(page, study.url)
        code = srv.enrol("P01")
        join(page, code, then=None)
        srv.act(code, "start")
        page.get_by_role("button", name=AGREE).click()
        page.get_by_role("button", name="Start").wait_for()
        settle_frames(page)
        page.get_by_role("button", name="Start").click()
        page.get_by_role("button", name="Close the gripper (G)").wait_for()
        live = srv.session(code)
        assert wait_until(lambda: live.scene_view is not None and live.scene_view.frames_sent >= 1)
        trial = live.run.trial
        start = trial.poses().gripper.copy()
        cam = live.page.client.camera
        # grab the vertical arrow above the gripper and pull it 30 cm down, through the table
        wait_camera_still(live)
        box = canvas_box(page)
        grab = tuple(page_pixel(page, cam, start + np.array([0.0, 0.0, 0.2]), box=box))
        end = tuple(page_pixel(page, cam, start + np.array([0.0, 0.0, -0.1]), box=box))
        drag_until(page, grab, end, lambda: trial.poses().gripper[2] < start[2] - 0.1, steps=8)
        floor = trial.scene.reach.lo[2]
        assert trial.poses().gripper[2] < start[2] - 0.1, "the handle was not dragged"

        def handle_on_gripper() -> bool:  # the handle floats HANDLE_OFFSET_M above its point
            gizmo = live.page.handle.gizmo
            at = np.asarray(gizmo.position) if gizmo is not None else np.full(3, np.inf)
            above = trial.poses().gripper + np.array([0.0, 0.0, HANDLE_OFFSET_M])
            return float(np.linalg.norm(at - above)) < 0.01

        # let go past the reach: the input is no longer dragged (a clamp sent to it as a new
        # target marked it dragged again, and the handle stayed where it was let go)
        assert wait_until(lambda: not live.input.source.dragging, timeout=10)
        assert wait_until(handle_on_gripper, timeout=10)
        assert trial.poses().gripper[2] > floor - 0.01  # stopped at the reach, not below
        screenshot(page, screenshots, "relative-released")
    finally:
        study.stop()

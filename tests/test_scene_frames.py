"""The scene sends a frame only when the participant could see something change
(``study.server.page_scene.SceneView``, ``STILL_M``): a still or settling arm costs the page
no redraws, and every visible motion is sent."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest
import viser

from app.robot.scene import Scene, build_scene
from study.protocol.loader import load_protocol
from study.server.page_scene import STILL_M, SceneView

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def scene() -> Scene:
    protocol = load_protocol(ROOT / "protocols" / "dragan2013.toml")
    return build_scene(next(iter(protocol.scenes.values())))


@pytest.fixture
def view(scene: Scene) -> Iterator[SceneView]:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        yield SceneView(server, scene.model, table_top=scene.spec.table.top_z)
    finally:
        server.stop()


def _poses(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    return data.xpos.copy(), data.xmat.copy()


def test_a_still_arm_is_sent_once(scene: Scene, view: SceneView) -> None:
    xpos, xmat = _poses(scene)
    for _ in range(10):
        view.render(xpos, xmat, gripper=xpos[-1])
    assert view.frames_sent == 1


def test_settling_below_a_pixel_is_not_sent_until_it_adds_up(scene: Scene, view: SceneView) -> None:
    xpos, xmat = _poses(scene)
    view.render(xpos, xmat)
    step = STILL_M / 4  # the posture settling after the keys are let go: 0.075 mm a frame
    moved = xpos.copy()
    for _ in range(3):
        moved[5] += step
        view.render(moved, xmat)
    assert view.frames_sent == 1
    moved[5] += step  # now STILL_M from the frame the page shows
    view.render(moved, xmat)
    assert view.frames_sent == 2


def test_every_visible_motion_is_sent(scene: Scene, view: SceneView) -> None:
    xpos, xmat = _poses(scene)
    view.render(xpos, xmat)
    for k in range(1, 6):  # a key held: 1 mm a frame at 0.1 m/s and 100 frames/s
        moved = xpos.copy()
        moved[3:] += 1e-3 * k
        view.render(moved, xmat)
    turned = xmat.copy()
    turned[4, 0] += 2 * STILL_M  # a hand turning by a fraction of a degree
    view.render(xpos, turned)
    assert view.frames_sent == 7

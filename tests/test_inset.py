"""The view from above (study.server.inset): what it shows, where, how often, and that its
JPEG bytes never spell a condition word."""

from __future__ import annotations

import io
import math
import threading
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
from PIL import Image

import study.server.inset as inset
from app.robot import Simulation, build_scene
from app.robot.task_view import task_view
from study.protocol import load_protocol
from study.server.inset import (
    InsetError,
    InsetJob,
    InsetLoop,
    InsetRenderer,
    encode_jpeg,
    top_down_camera,
)

ROOT = Path(__file__).resolve().parents[1]
SIZE = (320, 240)


@pytest.fixture(scope="module")
def paper() -> object:
    return load_protocol(ROOT / "protocols" / "dragan2013.toml")


def _rendered(scene_name: str, paper: object, *, q: np.ndarray | None = None):
    scene = build_scene(paper.scenes[scene_name])  # type: ignore[attr-defined]
    sim = Simulation(scene, physics_dt=0.0025)
    if q is not None:
        sim.data.qpos[:7] = q
        mujoco.mj_forward(sim.model, sim.data)
    camera = top_down_camera(scene, view_azimuth_deg=task_view(scene).azimuth_deg, aspect=4 / 3)
    renderer = InsetRenderer(scene, sim.model, camera=camera, size=SIZE)
    try:
        return scene, sim, camera, renderer.render(sim.poses())
    finally:
        renderer.close()


def test_up_in_the_picture_is_away_in_the_task_view(paper: object) -> None:
    scene = build_scene(paper.scenes["easy"])  # type: ignore[attr-defined]
    for azimuth in (195.0, 225.0, 240.0):
        camera = top_down_camera(scene, view_azimuth_deg=azimuth, aspect=4 / 3)
        a = math.radians(azimuth)
        away = -np.array([math.cos(a), math.sin(a), 0.0])  # the task camera's forward
        x0, y0 = camera.pixel(np.zeros(3), width=320, height=240)
        x1, y1 = camera.pixel(0.1 * away, width=320, height=240)
        assert y1 < y0 - 30 and abs(x1 - x0) < 1e-6


def test_each_object_appears_where_the_camera_says_in_its_own_colour(paper: object) -> None:
    scene, sim, camera, image = _rendered("easy", paper)
    assert image.shape == (240, 320, 3)
    for obj, body in zip(scene.spec.objects, scene.object_body_ids, strict=True):
        x, y = camera.pixel(sim.poses().xpos[body], width=320, height=240)
        assert 20 < x < 300 and 20 < y < 220, "the task's objects are in the picture"
        colour = image[round(y), round(x)].astype(float)
        expected = 255 * np.asarray(obj.rgba[:3])
        # the object's own colour at its centre (lit from above), not the table's
        cos = colour @ expected / (np.linalg.norm(colour) * np.linalg.norm(expected))
        assert cos > 0.97, (obj.name, colour, expected)


def test_at_the_grasp_the_gripper_mark_sits_on_the_object(paper: object) -> None:
    """From above the hand covers the object; its outline and the gripper's cross are drawn
    over the hand, the cross in the outline."""
    scene0 = build_scene(paper.scenes["training"])  # type: ignore[attr-defined]
    q = np.asarray(scene0.goals.configurations[scene0.target_index], float)
    scene, sim, camera, image = _rendered("training", paper, q=q)
    target = sim.poses().xpos[scene.object_body_ids[scene.target_index]]
    gx, gy = camera.pixel(sim.poses().gripper, width=320, height=240)
    ox, oy = camera.pixel(target, width=320, height=240)
    assert math.hypot(gx - ox, gy - oy) < 4
    r = scene.spec.objects[scene.target_index].size[0] * 240 / camera.extent_m
    ring = image[round(oy), round(ox + r)].astype(float)  # on the outline: the mug's red
    assert ring[0] > ring[1] + 60 and ring[0] > ring[2] + 60, ring


def test_a_gripper_outside_the_picture_is_pointed_at_from_the_edge(paper: object) -> None:
    scene = build_scene(paper.scenes["easy"])  # type: ignore[attr-defined]
    sim = Simulation(scene, physics_dt=0.0025)
    camera = top_down_camera(scene, view_azimuth_deg=195.0, aspect=4 / 3)
    renderer = InsetRenderer(scene, sim.model, camera=camera, size=SIZE)
    try:
        poses = sim.poses()
        inside = renderer.render(poses)
        far = type(poses)(poses.xpos, poses.xmat, np.array([0.3, 0.45, 0.2]))
        assert not (0 <= camera.pixel(far.gripper, width=320, height=240)[0] < 320)
        outside = renderer.render(far)
    finally:
        renderer.close()
    x, _ = camera.pixel(far.gripper, width=320, height=240)
    edge = slice(0, 30) if x < 0 else slice(290, 320)
    darker = inside[:, edge].mean(axis=2) - outside[:, edge].mean(axis=2)
    assert (darker > 80).sum() > 20, "a dark arrow at the edge nearest the gripper"


def test_no_jpeg_spells_a_condition_word() -> None:
    rng = np.random.default_rng(3)
    image = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    plain = encode_jpeg(image, words=())
    body = plain[plain.index(b"\xff\xda") + 20 : -2].lower()  # the picture's data, not its tables
    word = next(
        body[i : i + 3].decode()
        for i in range(len(body) - 3)
        if all(97 <= c <= 122 for c in body[i : i + 3])
    )  # three letters this picture's JPEG spells at quality 80
    clean = encode_jpeg(image, words=(word.upper(),))
    assert word.encode() not in clean.lower()
    assert Image.open(io.BytesIO(clean)).size == (320, 240)
    with pytest.raises(InsetError, match="frame dropped"):
        encode_jpeg(image, words=("jfif",))  # in every JPEG's header


def test_the_loop_draws_only_what_changed_and_stops_cleanly(paper: object) -> None:
    scene = build_scene(paper.scenes["easy"])  # type: ignore[attr-defined]
    sim = Simulation(scene, physics_dt=0.0025)
    key = [0]
    got: list[bytes] = []
    job = lambda: InsetJob(  # noqa: E731
        key=key[0],
        scene=scene,
        model=sim.model,
        view_azimuth_deg=225.0,
        poses=sim.poses(),
        words=("easy", "hard"),
    )
    loop = InsetLoop(name="inset-test", job=job, sink=got.append, rate_hz=30.0).start()
    try:
        deadline = time.monotonic() + 20
        while not got and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        assert len(got) == 1, "the same poses are drawn once"
        key[0] = 1
        deadline = time.monotonic() + 10
        while len(got) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(got) == 2 and loop.camera is not None
    finally:
        loop.stop()
    assert not loop.alive and loop.failed is None


def test_a_renderer_that_cannot_start_turns_the_picture_off(
    paper: object, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_gl(width: int, height: int) -> None:
        raise RuntimeError("no OpenGL here")

    monkeypatch.setattr(inset, "gl_context", no_gl)
    scene = build_scene(paper.scenes["easy"])  # type: ignore[attr-defined]
    sim = Simulation(scene, physics_dt=0.0025)
    done = threading.Event()
    loop = InsetLoop(
        name="inset-test",
        job=lambda: InsetJob(
            key=0,
            scene=scene,
            model=sim.model,
            view_azimuth_deg=225.0,
            poses=sim.poses(),
            words=(),
        ),
        sink=lambda _jpeg: done.set(),
    ).start()
    deadline = time.monotonic() + 10
    while loop.alive and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not loop.alive and not done.is_set()
    assert loop.failed is not None and "no OpenGL here" in loop.failed

"""The task view shows every object unoccluded by the arm, checked with MuJoCo's renderer.

For each scene of every shipped protocol the chosen camera pose is rendered (segmentation) at
the start and along a direct reach to each goal, once with the arm and once with the arm's geoms
moved out of the ``mjvScene``; each object keeps at least 80 % of its pixels and lies in the part
of the canvas the control panel leaves free. Today's default view fails that check (issue 10).
At the gripper each of the handle's axes moves its image across the screen, not into it (issue
20): the view along the table that the first search chose fails that.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import tomllib
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest

from app.robot.errors import RobotError
from app.robot.scene import Scene, build_scene
from app.robot.scene_spec import SceneSpec
from app.robot.task_view import (
    DEFAULT_ASPECT,
    DEFAULT_USABLE_WIDTH,
    MIN_AXIS_ANGLE_DEG,
    MIN_AXIS_SHARE,
    VISER_DEFAULT_FOV_DEG,
    TaskView,
    TaskViewError,
    reach_configurations,
    task_view,
    view_at,
    visible_fractions,
)
from study.protocol.loader import load_protocol
from study.server.page_scene import scene_view, task_center

ROOT = Path(__file__).resolve().parents[1]
HEIGHT = 360
WIDTH = round(HEIGHT * DEFAULT_ASPECT)
MIN_PIXELS_VISIBLE = 0.8


def _protocol_scenes() -> Iterator[tuple[str, str]]:
    for path in sorted((ROOT / "protocols").glob("*.toml")):
        if "scenes" in tomllib.loads(path.read_text()):  # population.toml is not a protocol
            for name in load_protocol(path).scenes:
                yield path.name, name


SCENES = list(_protocol_scenes())


def _scene(protocol: str, name: str) -> Scene:
    return build_scene(load_protocol(ROOT / "protocols" / protocol).scenes[name])


def _todays_view(scene: Scene) -> TaskView:
    """``study.server.live`` today: ``frame_task`` defaults around ``task_center``, viser's fov."""
    centre, distance = task_center(
        np.vstack([scene.start_ee, np.asarray(scene.goals.positions, float)])
    )
    return view_at(
        centre,
        distance=distance,
        azimuth_deg=205.0,
        elevation_deg=35.0,
        fov_rad=math.radians(VISER_DEFAULT_FOV_DEG),
    )


@dataclasses.dataclass
class Pixels:
    """Pixel counts per pose (rows) and object (columns)."""

    with_arm: np.ndarray
    without_arm: np.ndarray
    outside_usable: np.ndarray
    gripper: np.ndarray

    @property
    def fractions(self) -> np.ndarray:
        return self.with_arm / np.maximum(self.without_arm, 1)


_RENDERED: dict[tuple[str, str], Pixels] = {}


def _pixels(scene: Scene, view: TaskView) -> Pixels:
    """:func:`_render_pixels`, once per scene and view: most protocols share the paper's
    scenes (20 scenes, 7 different), and rendering is this module's cost (4-7 s a scene). The
    key is the whole scene description and view, so a protocol whose scene differs in anything
    is rendered on its own."""
    key = (repr(scene.spec), repr(view))
    if key not in _RENDERED:
        _RENDERED[key] = _render_pixels(scene, view)
    return _RENDERED[key]


def _render_pixels(scene: Scene, view: TaskView) -> Pixels:
    model = copy.deepcopy(scene.model)
    model.vis.global_.fovy = view.fov_deg
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, WIDTH)
    model.vis.global_.offheight = max(model.vis.global_.offheight, HEIGHT)
    objects = set(scene.object_body_ids)
    arm_geoms = {
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] != 0 and model.geom_bodyid[g] not in objects
    }
    fingers = [g for g in range(model.ngeom) if model.geom_bodyid[g] in scene.finger_body_ids]
    usable = round(DEFAULT_USABLE_WIDTH * WIDTH)
    data = mujoco.MjData(model)
    qs = reach_configurations(scene)
    shape = (len(qs), len(scene.object_geom_ids))
    out = Pixels(np.zeros(shape), np.zeros(shape), np.zeros(shape), np.zeros(len(qs)))
    with mujoco.Renderer(model, height=HEIGHT, width=WIDTH) as renderer:
        renderer.enable_segmentation_rendering()
        for k, q in enumerate(qs):
            data.qpos[:7] = q
            data.qpos[7:9] = scene.spec.gripper_open
            mujoco.mj_forward(model, data)
            for arm in (True, False):
                renderer.update_scene(data, camera=view.mjv_camera())
                if not arm:
                    for i in range(renderer.scene.ngeom):
                        geom = renderer.scene.geoms[i]
                        if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM and geom.objid in arm_geoms:
                            geom.pos[:] = (0.0, 0.0, -100.0)
                seg = renderer.render()
                # an int: numpy compares an array with mujoco's enum object one pixel at a
                # time in Python (0.12 s a frame, nearly all of this module's CPU)
                is_geom = seg[:, :, 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
                for j, gid in enumerate(scene.object_geom_ids):
                    mask = is_geom & (seg[:, :, 0] == gid)
                    if arm:
                        out.with_arm[k, j] = mask.sum()
                    else:
                        out.without_arm[k, j] = mask.sum()
                        out.outside_usable[k, j] = mask[:, usable:].sum()
                if arm:
                    out.gripper[k] = (is_geom & np.isin(seg[:, :, 0], fingers)).sum()
    return out


@pytest.mark.parametrize(("protocol", "name"), SCENES)
def test_task_view_shows_every_object_and_the_gripper(protocol: str, name: str) -> None:
    scene = _scene(protocol, name)
    view = scene_view(scene)  # the page's: room for the handle above the gripper
    assert view is not None
    px = _pixels(scene, view)
    assert px.without_arm.min() >= 50, "every object is in the frame, large enough to count"
    assert px.outside_usable.sum() == 0, "no object under the control panel"
    assert px.gripper.min() > 0, "the gripper is visible in every pose"
    assert px.fractions.min() >= MIN_PIXELS_VISIBLE, px.fractions.round(3)
    # the ray-cast estimate agrees with the renderer
    assert np.abs(visible_fractions(scene, view) - px.fractions).max() < 0.1
    assert view.visible_fraction == pytest.approx(visible_fractions(scene, view).min())


@pytest.mark.parametrize(("protocol", "name"), SCENES)
def test_each_handle_axis_moves_the_gripper_across_the_screen(protocol: str, name: str) -> None:
    """At the gripper, in every checked pose, a step along x, y or z moves its image at least
    70 % as far as a step across the line of sight, and no two axes' images lie within 45 deg
    of each other (the paper's scenes); a scene whose objects no such view shows (memory3's
    three objects) gets the most legible view that shows them all."""
    scene = _scene(protocol, name)
    view = scene_view(scene)
    assert view is not None and view.legibility is not None
    legibility = view.legibility
    if protocol != "memory3.toml":
        assert legibility.ok(min_share=MIN_AXIS_SHARE, min_angle_deg=MIN_AXIS_ANGLE_DEG), legibility
    else:
        assert min(legibility.shares) >= 0.6 and legibility.min_angle_deg >= 35, legibility
    assert 90 < view.azimuth_deg < 270, "behind the robot: away from the base is away from you"


def test_the_view_along_the_table_hid_sideways_motion() -> None:
    """The bug this fixes (issue 20): the paper's easy scene was seen from azimuth 250 deg,
    where the gripper's sideways axis (y) pointed mostly into the screen."""
    scene = _scene("dragan2013.toml", "easy")
    old = task_view(
        scene,
        azimuths_deg=(250.0,),
        elevations_deg=(30.0,),
        min_axis_share=0.0,
        min_axis_angle_deg=0.0,
    )
    assert old.legibility is not None and old.legibility.shares[1] < 0.6, old.legibility
    assert old.legibility.min_angle_deg < 40


# The easy scene of protocols/dragan2013.toml when the bug was found (issue 10): a fixed layout,
# so the test keeps documenting the bug while the protocol's layouts change.
ISSUE10_EASY = {
    "target": "bottle",
    "start_q": [0.0, -0.339, 0.0, -2.65, 0.0, 2.311, 0.785],
    "reach": {"min": [0.2, -0.45, 0.02], "max": [0.75, 0.45, 0.6]},
    "objects": [
        {
            "name": "bottle",
            "shape": "cylinder",
            "size": [0.03, 0.08],
            "position": [0.55, 0.3, 0.08],
        },
        {
            "name": "box",
            "shape": "box",
            "size": [0.025, 0.025, 0.05],
            "position": [0.45, 0.06, 0.05],
        },
    ],
}


def test_todays_default_view_hides_the_bottle_behind_the_arm() -> None:
    """The bug this fixes: azimuth 205, elevation 35 around ``task_center`` (viser's 75 deg fov)
    hides half the bottle at the start and all of it while reaching; the task view does not."""
    scene = build_scene(SceneSpec.from_dict(ISSUE10_EASY, where="scenes.easy"))
    today = _render_pixels(scene, _todays_view(scene)).fractions
    assert today[0, 0] < MIN_PIXELS_VISIBLE, today.round(3)  # the bottle, at the start
    assert today[:, 0].min() < 0.05, today.round(3)  # and while reaching
    assert _render_pixels(scene, task_view(scene)).fractions.min() >= MIN_PIXELS_VISIBLE


def test_view_geometry_is_consistent() -> None:
    scene = _scene(*SCENES[0])
    view = task_view(scene)
    offset = np.subtract(view.position, view.look_at)
    assert np.linalg.norm(offset) == pytest.approx(view.distance)
    assert math.degrees(math.asin(offset[2] / view.distance)) == pytest.approx(view.elevation_deg)
    assert math.degrees(math.atan2(offset[1], offset[0])) % 360 == pytest.approx(
        view.azimuth_deg % 360
    )
    assert view.up == (0.0, 0.0, 1.0)
    assert task_view(scene) is view, "cached per scene"
    with pytest.raises(dataclasses.FrozenInstanceError):
        view.distance = 2.0  # type: ignore[misc]


def test_unreachable_threshold_names_the_scene_and_the_best_fraction() -> None:
    scene = _scene(*SCENES[0])
    with pytest.raises(TaskViewError, match=rf"scene {scene.name!r}: .* only \d+% .*need 101%"):
        task_view(scene, min_visible=1.01)
    assert issubclass(TaskViewError, RobotError)


def test_a_frame_too_narrow_is_an_error() -> None:
    scene = _scene(*SCENES[0])
    with pytest.raises(TaskViewError, match="no viewpoint keeps every object"):
        task_view(scene, usable_width=0.3, margin=0.29, distance_factors=(1.0,))

"""The 3D scene a participant sees: a MuJoCo model rendered by mjviser with batched meshes.

mjviser names scene nodes after MuJoCo bodies and geoms (``panda_rightfinger`` ...). Node
names reach the browser, so :class:`NeutralNames` rewrites every path component to an opaque
id (``/n7/n12``) before viser sees it: no model name, hence no condition word, is sent.

Poses come from the control thread as snapshots ``(xpos (nbody,3), xmat (nbody,9))``;
:meth:`SceneView.render` sends one frame (about 0.6 ms) and is called at up to 60 Hz by a
:class:`study.server.loop.PacedLoop`, independent of the control rate.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import viser
from mjviser import ViserMujocoScene

from app.robot.task_view import TaskView, TaskViewError, task_view
from study.server.intent_cue import IntentCue, IntentGoals

LOGGER = logging.getLogger("study.server.scene")

ORBIT_MIN_M = 0.25
ORBIT_MAX_M = 2.5

_KEEP = frozenset({"", "fixed_bodies", "bodies"})


class NeutralNames:
    """Maps scene-node path components to opaque ids, the same component to the same id."""

    def __init__(self, prefix: str = "n") -> None:
        self._prefix = prefix
        self._ids: dict[str, str] = {}
        self._lock = threading.Lock()

    def __call__(self, path: str) -> str:
        parts = path.split("/")
        with self._lock:
            out = [
                p if p in _KEEP else self._ids.setdefault(p, f"{self._prefix}{len(self._ids)}")
                for p in parts
            ]
        return "/".join(out)


class _NeutralSceneApi:
    """Proxy of a viser ``SceneApi`` whose ``add_*`` methods get neutral node names. The
    floor's grid is not drawn: its shader runs on most of the screen and cost a third of a
    software-WebGL frame (12 -> 19 frames/s while the arm moves); the table is the scene's
    ground for the participant. Without ``shadows`` no mesh asks to receive them: mjviser lays
    a shadow-catching overlay (``receive_shadow=0.2``) over the table and the other fixed
    bodies, fully transparent when no light casts shadows, yet shaded pixel by pixel (1366 x
    768 at a fixed pixel ratio, software WebGL, windows paired in one page: 13.0-13.7 ->
    14.1-14.9 frames/s while the arm moves; the picture the same to the pixel)."""

    def __init__(self, scene: Any, names: NeutralNames, *, shadows: bool) -> None:
        self._scene = scene
        self._names = names
        self._shadows = shadows

    def __getattr__(self, attr: str) -> Any:
        value = getattr(self._scene, attr)
        if not attr.startswith("add_") or not callable(value):
            return value

        def add(name: str, *args: Any, **kwargs: Any) -> Any:
            if attr == "add_grid":
                return None
            if not self._shadows and kwargs.get("receive_shadow"):
                kwargs["receive_shadow"] = False
            return value(self._names(name), *args, **kwargs)

        return add


class _NeutralTarget:
    """What mjviser needs of a ``ViserServer``: ``scene``, ``atomic()``, ``flush()``."""

    def __init__(
        self, target: viser.ViserServer | viser.ClientHandle, names: NeutralNames, *, shadows: bool
    ) -> None:
        self.scene = _NeutralSceneApi(target.scene, names, shadows=shadows)
        self.atomic = target.atomic
        self.flush = target.flush
        self.gui = target.gui


def frame_task(
    camera: viser.CameraHandle,
    *,
    look_at: np.ndarray,
    distance: float = 1.6,
    azimuth_deg: float = 205.0,
    elevation_deg: float = 35.0,
) -> None:
    """Point ``camera`` at ``look_at`` from behind-and-above the robot base, z up."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    offset = distance * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    camera.up_direction = (0.0, 0.0, 1.0)
    camera.position = tuple(np.asarray(look_at, float) + offset)
    camera.look_at = tuple(np.asarray(look_at, float))


def task_center(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Where to look and from how far: the centre of ``points`` (the start of the gripper and
    the objects, (n, 3)) and a distance that keeps them all in view."""
    pts = np.asarray(points, float).reshape(-1, 3)
    center = pts.mean(axis=0)
    spread = float(np.max(np.linalg.norm(pts - center, axis=1))) if len(pts) > 1 else 0.3
    return center, max(1.1, 1.0 + 2.0 * spread)


HANDLE_HEADROOM_M = 0.3
"""Space kept in the task view above the gripper: the handle floats there
(``study.server.page_handle.HANDLE_OFFSET_M``, then its arrows)."""


def scene_view(scene: Any) -> TaskView | None:
    """``scene``'s task view (:func:`app.robot.task_view.task_view`: every object and the
    gripper unoccluded by the arm, left of the control panel, each handle axis across the
    screen, room for the handle), or None when no view shows it well enough (logged)."""
    try:
        return task_view(scene, headroom_m=HANDLE_HEADROOM_M)
    except TaskViewError as exc:
        LOGGER.warning("scene %s: %s; using the plain framing", scene.name, exc)
        return None


def frame_scene(camera: viser.CameraHandle, scene: Any) -> TaskView | None:
    """Point ``camera`` at ``scene``'s task view (:func:`scene_view`) and return it; a scene no
    view can show well enough falls back to the plain framing (and None)."""
    view = scene_view(scene)
    if view is None:
        center, distance = task_center(
            np.vstack([scene.start_ee, np.asarray(scene.goals.positions, float)])
        )
        frame_task(camera, look_at=center, distance=distance)
        return None
    camera.fov = view.fov_rad
    camera.up_direction = view.up
    camera.position = view.position
    camera.look_at = view.look_at
    # zoom stays between a close look at the gripper and the whole table in view
    camera.min_orbit_distance = ORBIT_MIN_M
    camera.max_orbit_distance = max(ORBIT_MAX_M, 1.5 * view.distance)
    return view


REACH_NODE = "/cue/reach"
REACH_COLOR = (70, 100, 140)
"""Slate blue: unlike the table, the objects and the intent ring (charcoal)."""
REACH_LINE_M = 0.006


def frame_mesh(
    lo: tuple[float, float], hi: tuple[float, float], *, width: float, z: float
) -> tuple[np.ndarray, np.ndarray]:
    """A flat rectangular frame at height ``z`` whose outer edge is the rectangle ``lo``..``hi``
    (xy) and whose band is ``width`` wide: ``(vertices (8, 3), faces (8, 3))``."""
    (x0, y0), (x1, y1) = lo, hi
    w = min(width, (x1 - x0) / 2, (y1 - y0) / 2)
    outer = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    inner = [(x0 + w, y0 + w), (x1 - w, y0 + w), (x1 - w, y1 - w), (x0 + w, y1 - w)]
    vertices = np.array([(x, y, z) for x, y in outer + inner], dtype=np.float32)
    faces = []
    for i in range(4):
        j = (i + 1) % 4
        faces += [(i, j, 4 + j), (i, 4 + j, 4 + i)]
    return vertices, np.array(faces, dtype=np.uint32)


def reach_footprint(
    reach_lo: np.ndarray, reach_hi: np.ndarray, table: Any
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The reach box's footprint on the table (xy, clipped to the table top), or None when it
    misses the table."""
    c, h = np.asarray(table.center, float), np.asarray(table.half_size, float)
    lo = np.maximum(np.asarray(reach_lo, float)[:2], c - h)
    hi = np.minimum(np.asarray(reach_hi, float)[:2], c + h)
    if np.any(hi - lo <= 0):
        return None
    return (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1]))


class SceneView:
    """One participant's view of one simulated scene (per-client nodes, neutral names), with
    a depth cue under the gripper: a thin vertical rod down to the table and a dark disc on
    the table (two small meshes moved per frame; no shadows, which software WebGL cannot
    afford). With ``reach`` (the footprint ``(lo, hi)`` from :func:`reach_footprint`), the
    limit of the participant's reach drawn on the table as a thin frame (one static mesh).
    With ``goals``, the robot's intent too: a ring around the predicted object
    (:class:`study.server.intent_cue.IntentCue`); without, no such node exists."""

    def __init__(
        self,
        target: viser.ViserServer | viser.ClientHandle,
        model: mujoco.MjModel,
        *,
        on_frame: Callable[[], None] | None = None,
        shadows: bool = False,
        table_top: float | None = None,
        goals: IntentGoals | None = None,
        reach: tuple[tuple[float, float], tuple[float, float]] | None = None,
    ) -> None:
        # Shadow maps cost a 10-50x frame rate drop in software WebGL (measured: 0.2-1.3 fps
        # with, 13-30 fps without, for the Panda scene in headless Chromium on 2 cores).
        target.scene.configure_default_lights(cast_shadow=shadows)
        self.names = NeutralNames()
        neutral = _NeutralTarget(target, self.names, shadows=shadows)
        self._scene = ViserMujocoScene(neutral, model, num_envs=1)  # type: ignore[arg-type]
        self._scene.camera_tracking_enabled = False
        # Image-based lighting costs about two thirds of a software-WebGL frame (measured: 8
        # -> 21 frames/s while the arm moves); plain lights light the scene well enough.
        target.scene.configure_environment_map(hdri=None)
        target.scene.add_light_ambient("/lights/ambient", intensity=0.7)
        self._on_frame = on_frame
        self._flush = target.flush
        self._table_top = table_top
        self._drop = self._disc = None
        if table_top is not None:
            scene = target.scene
            # a 1 m rod of 2 mm radius, stretched to the gripper's height each frame (a mesh:
            # screen-space lines cost a sixth of a software-WebGL frame)
            self._drop = scene.add_cylinder(
                "/cue/line", radius=0.002, height=1.0, color=(40, 40, 40), visible=False
            )
            self._disc = scene.add_cylinder(
                "/cue/disc", radius=0.018, height=0.002, color=(30, 30, 30), visible=False
            )
        self.reach = None
        if reach is not None:
            vertices, faces = frame_mesh(
                *reach, width=REACH_LINE_M, z=float(table_top or 0.0) + 0.0012
            )
            self.reach = target.scene.add_mesh_simple(
                REACH_NODE,
                vertices,
                faces,
                color=REACH_COLOR,
                side="double",
                cast_shadow=False,
                receive_shadow=False,
            )
        self.intent = IntentCue(target.scene, goals) if goals is not None else None
        self.frames_sent = 0
        self.render_s: deque[float] = deque(maxlen=4096)
        """Wall time of the last renders (seconds), for the server benchmark."""

    def render(
        self,
        xpos: np.ndarray,
        xmat: np.ndarray,
        *,
        gripper: np.ndarray | None = None,
        intent: tuple[int, float] | None = None,
    ) -> None:
        """Send one frame with body poses ``xpos (nbody,3)``, ``xmat (nbody,9)``, the depth
        cue under ``gripper`` (3,) and, if this view shows intent, the ring for ``intent`` =
        ``(predicted goal index, confidence)`` (None: no prediction yet, ring hidden)."""
        t = time.perf_counter()
        self._scene.update_from_arrays(
            np.asarray(xpos, float)[None], np.asarray(xmat, float).reshape(1, -1, 3, 3)
        )
        if gripper is not None and self._drop is not None and self._disc is not None:
            top = float(self._table_top or 0.0)
            x, y, z = (float(v) for v in gripper)
            height = max(z - top, 1e-3)
            self._drop.position = (x, y, top + height / 2)
            self._drop.scale = (1.0, 1.0, height)
            self._disc.position = (x, y, top + 0.001)
            if not self._drop.visible:
                self._drop.visible = self._disc.visible = True
        if self.intent is not None:
            predicted, confidence = intent if intent is not None else (-1, 0.0)
            self.intent.update(xpos, predicted, confidence)
        # mjviser flushes inside its atomic block, where viser cannot send yet; flushing again
        # here sends the frame now instead of after viser's 1/60 s window.
        self._flush()
        self.render_s.append(time.perf_counter() - t)
        self.frames_sent += 1
        if self._on_frame is not None:
            self._on_frame()

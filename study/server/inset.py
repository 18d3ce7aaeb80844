"""The view from above: a second, fixed picture of the run's table, so that depth is never guessed.

The task camera (``app.robot.task_view``) looks at the table obliquely; how far away or how far
to the side the gripper is stays ambiguous in one picture. The trial screen therefore also shows
the table straight from above, rendered by MuJoCo's offscreen renderer (``MUJOCO_GL=egl`` or
``osmesa``) from the same body poses the 3-D view gets:

* an orthographic camera looking down, turned so that "up" in the picture is "away" in the task
  view (image up = the task camera's horizontal forward ``-(cos a, sin a)``); it frames the
  objects and the gripper's start with 12 cm around them (:func:`top_down_camera`);
* the arm drawn half transparent (from above it would hide what lies under the hand), the reach
  limit as a frame on the table and a dark disc on the table under the gripper, as in the 3-D
  view; over everything, each object's footprint outlined in its colour and the gripper's point
  as a cross (seen through the hand), and a dark arrow at the edge toward a gripper outside the
  picture;
* 320 x 240 pixels, no multisampling, no shadows or reflections (about 6-10 ms a frame in
  software GL on these machines), JPEG at quality 80 (5-8 kB);
* at most ``rate_hz`` frames a second (15, so that a loaded machine still shows 10 or more),
  and no more than the page draws (``InsetJob.most_hz``, :mod:`study.server.draw_rate`), and
  only when something moved or the page's screen changed: a still arm costs nothing.

:class:`InsetLoop` runs in its own thread with its own model copy, ``MjData`` and GL context
(a context belongs to the thread that made it): the control thread only hands over the pose
snapshot it already makes for the 3-D view. Every JPEG is searched for the served protocol's
condition words (compressed bytes are random enough to spell one now and then) and re-encoded
at another quality until it spells none: nothing the page receives names a condition.
"""

from __future__ import annotations

import copy
import logging
import math
import os
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import cv2
import mujoco
import numpy as np

from app.robot import BodyPoses, Scene
from study.errors import StudyError
from study.server.draw_rate import Pacer
from study.server.loop import PacedLoop

LOGGER = logging.getLogger("study.server.inset")

INSET_HZ = 15.0
JPEG_QUALITY = 80
ARM_ALPHA = 0.3
MARGIN_M = 0.12
MIN_EXTENT_M = 0.35
DISC_RADIUS_M = 0.018
REACH_RGBA = (70 / 255, 100 / 255, 140 / 255, 1.0)
DISC_RGBA = (0.12, 0.12, 0.12, 1.0)
LINE_M = 0.008
EDGE_PX = 6
EDGE_RGB = (30, 30, 30)
OUTLINE_RGB = (40, 40, 40)
_SQUARE = ((-1, -1), (1, -1), (1, 1), (-1, 1))


@dataclass(frozen=True)
class TopDownCamera:
    """An orthographic camera looking straight down at ``lookat``; ``up`` is the world
    direction (unit, horizontal) that points up in the picture; ``extent_m`` the picture's
    height in metres."""

    lookat: tuple[float, float, float]
    up: tuple[float, float]
    extent_m: float
    aspect: float

    def mjv_camera(self) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance = 2.0
        cam.azimuth = math.degrees(math.atan2(self.up[1], self.up[0]))
        cam.elevation = -90.0
        cam.orthographic = 1
        return cam

    def pixel(self, point: np.ndarray, *, width: int, height: int) -> tuple[float, float]:
        """Where world ``point`` (x, y, ...) appears in a ``width`` x ``height`` picture."""
        up = np.asarray(self.up, float)
        right = np.array([up[1], -up[0]])  # up turned clockwise
        d = np.asarray(point, float)[:2] - np.asarray(self.lookat, float)[:2]
        scale = height / self.extent_m
        return (width / 2 + scale * float(d @ right), height / 2 - scale * float(d @ up))


def top_down_camera(
    scene: Scene, *, view_azimuth_deg: float, aspect: float, margin_m: float = MARGIN_M
) -> TopDownCamera:
    """The picture's camera for ``scene``, turned to match a task view at ``view_azimuth_deg``
    and framing the task: the objects and the gripper's start, ``margin_m`` around them (at
    least :data:`MIN_EXTENT_M` high), so that a 5 cm object spans about 25 pixels."""
    a = math.radians(view_azimuth_deg)
    up = np.array([-math.cos(a), -math.sin(a)])
    right = np.array([up[1], -up[0]])
    pts = [np.asarray(scene.start_ee, float)[:2]]
    for obj, pos in zip(scene.spec.objects, np.asarray(scene.goals.positions, float), strict=True):
        r = float(obj.footprint_radius)
        pts += [pos[:2] + r * np.array(d) for d in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    p = np.array(pts)
    u, v = p @ right, p @ up
    cu, cv = (u.min() + u.max()) / 2, (v.min() + v.max()) / 2
    extent = max(v.max() - v.min(), (u.max() - u.min()) / aspect) + 2 * margin_m
    centre = cu * right + cv * up
    return TopDownCamera(
        lookat=(float(centre[0]), float(centre[1]), float(scene.spec.table.top_z)),
        up=(float(up[0]), float(up[1])),
        extent_m=float(max(extent, MIN_EXTENT_M)),
        aspect=aspect,
    )


def encode_jpeg(rgb: np.ndarray, *, words: Iterable[str], quality: int = JPEG_QUALITY) -> bytes:
    """``rgb`` (h, w, 3) as JPEG bytes that spell no word of ``words`` in any letter case
    (re-encoded at the next lower quality until none occurs)."""
    bgr = np.ascontiguousarray(rgb[:, :, ::-1])
    banned = [w.lower().encode() for w in words if w]
    for q in range(quality, max(quality - 20, 10), -1):
        ok, buf = cv2.imencode(".jpg", bgr, [int(cv2.IMWRITE_JPEG_QUALITY), q])
        if not ok:
            break
        data = buf.tobytes()
        low = data.lower()
        if not any(w in low for w in banned):
            return data
    raise InsetError("no JPEG quality avoided the condition words; frame dropped")


class InsetError(StudyError, RuntimeError):
    """A frame of the view from above could not be made (no GL context, no clean JPEG)."""


class InsetRenderer:
    """Renders ``scene`` from above; use from one thread only (it owns a GL context)."""

    def __init__(
        self,
        scene: Scene,
        model: mujoco.MjModel,
        *,
        camera: TopDownCamera,
        size: tuple[int, int],
    ) -> None:
        self.scene = scene
        self.camera = camera
        self.width, self.height = size
        m = copy.copy(model)
        m.vis.global_.offwidth = max(m.vis.global_.offwidth, self.width)
        m.vis.global_.offheight = max(m.vis.global_.offheight, self.height)
        m.vis.quality.offsamples = 0
        m.vis.global_.fovy = camera.extent_m  # orthographic: the picture's height in metres
        objects = set(scene.object_body_ids)
        arm = np.array([b != 0 and b not in objects for b in m.geom_bodyid])
        m.geom_rgba[arm, 3] *= ARM_ALPHA
        mats = np.unique(m.geom_matid[arm & (m.geom_matid >= 0)])
        m.mat_rgba[mats, 3] *= ARM_ALPHA
        # even, glare-free light: the objects keep the colours the 3-D view shows
        m.vis.headlight.ambient[:] = 0.55
        m.vis.headlight.diffuse[:] = 0.35
        m.vis.headlight.specular[:] = 0.0
        m.light_specular[:] = 0.0
        self.model = m
        self.data = mujoco.MjData(m)
        mujoco.mj_kinematics(m, self.data)  # lights and cameras; geoms come from the poses
        self._body = m.geom_bodyid.copy()
        self._gpos = m.geom_pos.copy()
        rot = np.empty((m.ngeom, 9))
        for g in range(m.ngeom):
            mujoco.mju_quat2Mat(rot[g], m.geom_quat[g])
        self._grot = rot.reshape(-1, 3, 3)
        self._opt = mujoco.MjvOption()
        self._opt.sitegroup[:] = 0
        self._cam = camera.mjv_camera()
        self._gl = gl_context(self.width, self.height)
        self._gl.make_current()
        self._scene = mujoco.MjvScene(m, maxgeom=1000)
        for flag in ("mjRND_SHADOW", "mjRND_REFLECTION", "mjRND_SKYBOX"):
            self._scene.flags[getattr(mujoco.mjtRndFlag, flag)] = 0
        self._context = mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_100)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        self._rgb = np.empty((self.height, self.width, 3), np.uint8)
        self._perturb = mujoco.MjvPerturb()
        self._reach = _reach_geoms(scene)

    def render(self, poses: BodyPoses) -> np.ndarray:
        """The picture (h, w, 3) uint8 with the bodies at ``poses``."""
        d = self.data
        xmat = np.asarray(poses.xmat, float).reshape(-1, 3, 3)
        d.xpos[:] = poses.xpos
        d.xmat[:] = poses.xmat
        bm = xmat[self._body]
        d.geom_xpos[:] = poses.xpos[self._body] + np.einsum("gij,gj->gi", bm, self._gpos)
        d.geom_xmat[:] = np.einsum("gij,gjk->gik", bm, self._grot).reshape(-1, 9)
        scene = self._scene
        mujoco.mjv_updateScene(
            self.model, d, self._opt, self._perturb, self._cam, mujoco.mjtCatBit.mjCAT_ALL, scene
        )
        top = float(self.scene.spec.table.top_z)
        g = np.asarray(poses.gripper, float)
        disc = _geom_box((g[0], g[1], top + 0.0015), (DISC_RADIUS_M,) * 2, DISC_RGBA, cylinder=True)
        for kind, size, pos, rgba in [*self._reach, disc]:
            if scene.ngeom >= scene.maxgeom:
                break
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], kind, size, pos, _EYE, rgba)
            scene.ngeom += 1
        self._gl.make_current()
        mujoco.mjr_render(self._rect, scene, self._context)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._context)
        image = np.flipud(self._rgb).copy()
        self._outline(image, poses)
        return self._point_out(image, g)

    def _outline(self, image: np.ndarray, poses: BodyPoses) -> None:
        """Each object's footprint outlined in its colour and the gripper's point marked, over
        everything: under the hand, from above, they would be hidden."""
        w, h = self.width, self.height
        scale = h / self.camera.extent_m
        for obj, body in zip(self.scene.spec.objects, self.scene.object_body_ids, strict=True):
            centre = np.asarray(poses.xpos[body], float)
            colour = tuple(int(255 * c) for c in obj.rgba[:3])
            if obj.shape == "cylinder":
                x, y = self.camera.pixel(centre, width=w, height=h)
                r = max(2, round(obj.size[0] * scale))
                cv2.circle(image, (round(x), round(y)), r, OUTLINE_RGB, 4, cv2.LINE_AA)
                cv2.circle(image, (round(x), round(y)), r, colour, 2, cv2.LINE_AA)
            else:
                rot = np.asarray(poses.xmat[body], float).reshape(3, 3)
                hx, hy = obj.size[0], obj.size[1]
                corners = [centre + rot @ np.array([sx * hx, sy * hy, 0.0]) for sx, sy in _SQUARE]
                pts = np.array([self.camera.pixel(c, width=w, height=h) for c in corners])
                pts = pts.round().astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(image, [pts], True, OUTLINE_RGB, 4, cv2.LINE_AA)
                cv2.polylines(image, [pts], True, colour, 2, cv2.LINE_AA)
        x, y = self.camera.pixel(poses.gripper, width=w, height=h)
        c = (round(x), round(y))
        cv2.drawMarker(image, c, OUTLINE_RGB, cv2.MARKER_CROSS, 14, 3, cv2.LINE_AA)
        cv2.drawMarker(image, c, (250, 250, 250), cv2.MARKER_CROSS, 12, 1, cv2.LINE_AA)

    def _point_out(self, image: np.ndarray, gripper: np.ndarray) -> np.ndarray:
        """A gripper outside the picture is shown by an arrow at the picture's edge, pointing
        toward it (the picture frames the task, not all of the reach)."""
        w, h = self.width, self.height
        x, y = self.camera.pixel(gripper, width=w, height=h)
        if 0 <= x < w and 0 <= y < h:
            return image
        c = np.array([w / 2, h / 2])
        d = np.array([x, y]) - c
        k = min((w / 2 - EDGE_PX) / max(abs(d[0]), 1e-9), (h / 2 - EDGE_PX) / max(abs(d[1]), 1e-9))
        tip = c + k * d
        tail = tip - 18 * d / np.linalg.norm(d)
        cv2.arrowedLine(
            image,
            (int(tail[0]), int(tail[1])),
            (int(tip[0]), int(tip[1])),
            EDGE_RGB,
            thickness=3,
            tipLength=0.5,
        )
        return image

    def close(self) -> None:
        """Free the GL objects (from the thread that rendered)."""
        self._context.free()
        self._gl.free()


_Geom = tuple[int, np.ndarray, np.ndarray, np.ndarray]
_EYE = np.eye(3).reshape(-1)


def gl_context(width: int, height: int) -> Any:
    """An offscreen GL context for this thread: EGL, or OSMesa with ``MUJOCO_GL=osmesa``.
    Chosen here rather than by ``mujoco.Renderer``, whose choice is fixed by ``MUJOCO_GL`` as
    it was when ``mujoco`` was first imported (GLFW, which needs a display, if it was unset)."""
    if os.environ.get("MUJOCO_GL", "egl").lower() == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.egl import GLContext
    return GLContext(width, height)


def _geom_box(
    pos: tuple[float, float, float],
    half_xy: tuple[float, float],
    rgba: tuple[float, float, float, float],
    *,
    cylinder: bool = False,
) -> _Geom:
    if cylinder:
        kind, size = mujoco.mjtGeom.mjGEOM_CYLINDER, (half_xy[0], 0.0005, 0.0)
    else:
        kind, size = mujoco.mjtGeom.mjGEOM_BOX, (half_xy[0], half_xy[1], 0.0005)
    return (int(kind), np.array(size, float), np.array(pos, float), np.array(rgba, np.float32))


def _reach_geoms(scene: Scene) -> list[_Geom]:
    """The reach's footprint (clipped to the table) as four thin boxes on the table."""
    spec = scene.spec
    c, h = np.asarray(spec.table.center, float), np.asarray(spec.table.half_size, float)
    lo = np.maximum(np.asarray(scene.reach.lo, float)[:2], c - h)
    hi = np.minimum(np.asarray(scene.reach.hi, float)[:2], c + h)
    if np.any(hi <= lo):
        return []
    z, w = float(spec.table.top_z) + 0.001, LINE_M / 2
    (x0, y0), (x1, y1) = lo, hi
    mx, my = (x0 + x1) / 2, (y0 + y1) / 2
    hx, hy = (x1 - x0) / 2, (y1 - y0) / 2
    return [
        _geom_box((mx, y0 + w, z), (hx, w), REACH_RGBA),
        _geom_box((mx, y1 - w, z), (hx, w), REACH_RGBA),
        _geom_box((x0 + w, my, z), (w, hy), REACH_RGBA),
        _geom_box((x1 - w, my, z), (w, hy), REACH_RGBA),
    ]


@dataclass(frozen=True)
class InsetJob:
    """What to draw next: ``key`` changes whenever a new picture is due (new poses, another
    tab or screen); the scene, its model, the task view's azimuth, the poses and the words no
    frame may spell (the served protocol's condition words)."""

    key: object
    scene: Scene
    model: mujoco.MjModel
    view_azimuth_deg: float
    poses: BodyPoses
    words: tuple[str, ...]
    most_hz: float = INSET_HZ
    """Pictures a second the page can use (``study.server.draw_rate.inset_hz``)."""


class InsetLoop:
    """The view from above of one live session, in its own thread (module doc): ``job()`` says
    what to draw (None: nothing), ``sink(jpeg)`` shows it. A renderer that cannot start (no GL)
    is reported once and the loop stops; the page then keeps its blank picture."""

    def __init__(
        self,
        *,
        name: str,
        job: Callable[[], InsetJob | None],
        sink: Callable[[bytes], None],
        rate_hz: float = INSET_HZ,
        size: tuple[int, int] = (320, 240),
    ) -> None:
        self._job = job
        self._sink = sink
        self.size = size
        self._renderer: InsetRenderer | None = None
        self._done: object = None
        self._closing = False
        self.frames = 0
        self.render_s: deque[float] = deque(maxlen=512)
        """Wall time of the last renders incl. encoding (seconds)."""
        self.sent_at: deque[float] = deque(maxlen=512)
        """When (monotonic) the last pictures were handed to the page."""
        self.failed: str | None = None
        self.dropped = 0
        """Pictures not sent: no JPEG quality avoided a condition word (a word spelt by the
        JPEG format's own tables, such as "cdefghij", would drop them all)."""
        self._pacer = Pacer()
        self._loop = PacedLoop(self._step, rate_hz=rate_hz, name=name)

    def start(self) -> InsetLoop:
        self._loop.start()
        return self

    @property
    def alive(self) -> bool:
        return self._loop.alive

    @property
    def camera(self) -> TopDownCamera | None:
        """The camera of the scene drawn last (None before the first picture)."""
        r = self._renderer
        return None if r is None else r.camera

    def stop(self) -> None:
        """Stop the thread; it frees its GL context itself before it ends."""
        self._closing = True
        self._loop.stop(timeout=2.0)

    def _step(self) -> bool:
        if self._closing:
            self._close()
            return False
        job = self._job()
        if job is None or job.key == self._done:
            return True
        if not self._pacer.due(time.monotonic(), job.most_hz):
            return True
        t = time.perf_counter()
        try:
            renderer = self._renderer_for(job)
            jpeg = encode_jpeg(renderer.render(job.poses), words=job.words)
        except InsetError as exc:  # said once: it would repeat with every picture
            if not self.dropped:
                LOGGER.warning("view from above: %s", exc)
            self.dropped += 1
            self._done = job.key
            return True
        except Exception as exc:  # no GL context: say so once, keep the session going
            self.failed = f"{type(exc).__name__}: {exc}"
            LOGGER.warning("the view from above is off: %s", self.failed)
            self._close()
            return False
        self._done = job.key
        self._sink(jpeg)
        self.frames += 1
        self.render_s.append(time.perf_counter() - t)
        self.sent_at.append(time.monotonic())
        return True

    def _renderer_for(self, job: InsetJob) -> InsetRenderer:
        r = self._renderer
        if r is None or r.scene is not job.scene:
            self._close()
            w, h = self.size
            camera = top_down_camera(job.scene, view_azimuth_deg=job.view_azimuth_deg, aspect=w / h)
            r = self._renderer = InsetRenderer(job.scene, job.model, camera=camera, size=self.size)
        return r

    def _close(self) -> None:
        if self._renderer is not None:
            try:
                self._renderer.close()
            except Exception:
                LOGGER.debug("closing the inset renderer failed", exc_info=True)
            self._renderer = None


__all__ = [
    "INSET_HZ",
    "InsetError",
    "InsetJob",
    "InsetLoop",
    "InsetRenderer",
    "TopDownCamera",
    "encode_jpeg",
    "top_down_camera",
]

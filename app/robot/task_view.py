"""A camera pose per scene that shows every object and the gripper, unoccluded by the arm.

``task_view(scene)`` searches a small grid of viewpoints around the task's centre ``c`` (the
mean of the gripper's start and the grasp points) and returns the best as a :class:`TaskView`
for the browser's perspective camera (vertical field of view ``fov``, canvas aspect ``a``).

Poses checked: the start configuration and a direct reach to each goal, ``q(t) = q0 + t (qg -
q0)`` for ``t`` in ``reach_fractions`` (the grasp itself, ``t = 1``, is left out: there the hand
encloses the object by design). A viewpoint ``(azimuth, elevation, distance)`` puts the camera
at ``p = l + d (cos e cos a, cos e sin a, sin e)``; the look-at point ``l = c + s r`` is ``c``
panned along the camera's right vector ``r`` by ``s = (1 - u) d tan(fov/2) a`` so that ``c``
appears in the middle of the left ``u`` of the canvas (the control panel covers the rest). A
point ``x`` with camera coordinates ``(x_r, x_u, x_f)`` projects to ``(x_r / (x_f tan(fov/2) a),
x_u / (x_f tan(fov/2)))``; every object's corners, the gripper in every pose, the robot's base
and the table within ``context_m`` of them must project inside ``[-1 + m, 2u - 1 - m] x [-1 + m,
1 - m]``. For each (azimuth, elevation) the distance is
the smallest that satisfies this (bisection), times each of ``distance_factors``.

Legibility: each handle axis must move the gripper visibly across the screen, not along the line
of sight. At a point ``x`` (camera coordinates ``x_r, x_u, x_f``) a step along world axis ``e_i``
moves the image by ``s_i = (e_i . r - (x_r / x_f) e_i . f, e_i . u - (x_u / x_f) e_i . f)`` per
metre at unit depth (the projection's Jacobian times ``x_f``: ``|s_i|`` is about 1 across the
line of sight, 0 along it). At the gripper in every checked pose, a viewpoint is kept only if
every ``|s_i| >= min_axis_share`` and every two axes' images are at least ``min_axis_angle_deg``
apart (so no two arrows of the handle overlap). A camera looking along a table axis (azimuth 180
or 270 deg) fails: one of the arrows points into the screen; so does one whose axis is diagonal
while the gripper, off to the side of the picture, is seen along a table axis.

Visibility: each object's surface is sampled (area elements ``dA_i``, outward normals ``n_i``) and
a ray is cast from ``p`` to each sample with ``mujoco.mj_multiRay`` in every pose; a sample is
visible if the first geom hit is the object's own. The visible fraction is ``sum(w_i v_i) /
sum(w_i)`` with ``w_i = dA_i max(0, n_i . (p - x_i) / |p - x_i|)``, the sample's projected area,
so it estimates the fraction of the object's pixels. The chosen viewpoint maximises the worst
fraction over objects and poses among the legible ones; within ``tie_tolerance`` of the best,
the one nearest the default (azimuth 225 deg: behind the robot and to its right, looking across
the table's diagonal; elevation 35 deg), then the earliest of ``distance_factors``, wins. When
no legible viewpoint shows every object ``min_visible``, the most legible of those that do wins
(``TaskView.legibility`` says how legible it is). Deterministic, about 0.5-1 s per scene on 2
cores (3 s when no legible view shows every object); results are cached per scene.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from app.robot.errors import RobotError
from app.robot.scene import Scene

DEFAULT_FOV_DEG = 60.0
"""Vertical field of view the page sets (``client.camera.fov``); viser's own default is 75 deg."""
VISER_DEFAULT_FOV_DEG = 75.0
DEFAULT_ASPECT = 16 / 10
"""Canvas width / height assumed: a landscape page of about 1150 x 720 px."""
DEFAULT_USABLE_WIDTH = 2 / 3
"""Fraction of the canvas, from the left, not covered by the control panel (about 380 px)."""
DEFAULT_AZIMUTH_DEG = 225.0
DEFAULT_ELEVATION_DEG = 35.0
MIN_AXIS_SHARE = 0.7
"""Each world axis spans at least this fraction of its length across the screen."""
MIN_AXIS_ANGLE_DEG = 45.0
"""Any two world axes appear at least this far apart on the screen."""
_UP = (0.0, 0.0, 1.0)
_RAY_CUTOFF = 100.0  # m; mj_multiRay ignores every geom when the cutoff is negative


class TaskViewError(RobotError):
    """No viewpoint shows every object well enough; the message names the scene and the best."""


@dataclass(frozen=True, kw_only=True)
class TaskView:
    """A perspective camera pose, z up: what the page sets on ``client.camera``.

    ``position = look_at + distance (cos e cos a, cos e sin a, sin e)`` with ``a, e`` the azimuth
    and elevation in degrees (the convention of ``study.server.page_scene.frame_task``). ``fov_rad`` is the
    vertical field of view. ``visible_fraction`` is the worst visible fraction of any object in
    any checked pose (1.0: nothing hidden), estimated by ray casting.
    """

    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = _UP
    fov_rad: float
    distance: float
    azimuth_deg: float
    elevation_deg: float
    visible_fraction: float = math.nan
    legibility: AxisLegibility | None = None
    """How the world axes x, y, z appear across the screen at the gripper (worst over the
    checked poses; module doc), when the view was chosen by :func:`task_view`."""

    @property
    def fov_deg(self) -> float:
        return math.degrees(self.fov_rad)

    def mjv_camera(self) -> mujoco.MjvCamera:
        """The same pose as a MuJoCo free camera (set ``model.vis.global_.fovy = fov_deg``)."""
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.look_at
        cam.distance = self.distance
        cam.azimuth = (self.azimuth_deg + 180.0) % 360.0
        cam.elevation = -self.elevation_deg
        return cam


@dataclass(frozen=True)
class AxisLegibility:
    """``shares[i] = |s_i|``, the on-screen length of world axis ``i`` (x, y, z) per unit
    length across the line of sight, and ``min_angle_deg``, the smallest angle between two
    axes' images (undirected, 0..90 deg); the worst over the points it was taken at."""

    shares: tuple[float, float, float]
    min_angle_deg: float

    def ok(self, *, min_share: float, min_angle_deg: float) -> bool:
        return min(self.shares) >= min_share and self.min_angle_deg >= min_angle_deg


def axis_legibility(
    eye: np.ndarray, azimuth_deg: float, elevation_deg: float, points: np.ndarray
) -> AxisLegibility:
    """The world axes' images at ``points`` (n, 3) seen from ``eye`` looking at ``(azimuth,
    elevation)`` (module doc): the smallest share of each axis and the smallest angle."""
    r, u, f = _basis(azimuth_deg, elevation_deg)
    rel = np.asarray(points, float).reshape(-1, 3) - np.asarray(eye, float)
    xf = rel @ f
    kr, ku = (rel @ r) / xf, (rel @ u) / xf
    # images[n, i] = on-screen direction of axis i at point n (unit depth)
    images = np.stack(
        [np.stack([r[i] - kr * f[i], u[i] - ku * f[i]], axis=1) for i in range(3)], axis=1
    )
    shares = np.linalg.norm(images, axis=2)
    worst = 90.0
    for i in range(3):
        for j in range(i + 1, 3):
            c = np.abs((images[:, i] * images[:, j]).sum(axis=1)) / np.maximum(
                shares[:, i] * shares[:, j], 1e-12
            )
            worst = min(worst, float(np.degrees(np.arccos(np.minimum(c, 1.0))).min()))
    low = shares.min(axis=0)
    return AxisLegibility(shares=(float(low[0]), float(low[1]), float(low[2])), min_angle_deg=worst)


def view_at(
    look_at: np.ndarray | tuple[float, float, float],
    *,
    distance: float,
    azimuth_deg: float,
    elevation_deg: float,
    fov_rad: float,
    visible_fraction: float = math.nan,
    legibility: AxisLegibility | None = None,
) -> TaskView:
    """The :class:`TaskView` looking at ``look_at`` from ``distance`` at the given angles."""
    la = np.asarray(look_at, float).reshape(3)
    pos = la + distance * _direction(azimuth_deg, elevation_deg)
    return TaskView(
        position=_tuple3(pos),
        look_at=_tuple3(la),
        fov_rad=float(fov_rad),
        distance=float(distance),
        azimuth_deg=float(azimuth_deg),
        elevation_deg=float(elevation_deg),
        visible_fraction=float(visible_fraction),
        legibility=legibility,
    )


def task_centre(scene: Scene) -> np.ndarray:
    """The mean of the gripper's start and the grasp points, (3,)."""
    pts = np.vstack([scene.start_ee, np.asarray(scene.goals.positions, float)])
    return pts.mean(axis=0)


def reach_configurations(
    scene: Scene, *, reach_fractions: tuple[float, ...] = (0.25, 0.5, 0.75)
) -> np.ndarray:
    """The start configuration and ``start + t (goal - start)`` for each goal and ``t``, (k, 7)."""
    q0 = np.asarray(scene.start_q, float)
    qs = [q0]
    for qg in np.asarray(scene.goals.configurations, float):
        qs.extend(q0 + t * (qg - q0) for t in reach_fractions)
    return np.array(qs)


def visible_fractions(
    scene: Scene,
    view: TaskView,
    *,
    reach_fractions: tuple[float, ...] = (0.25, 0.5, 0.75),
) -> np.ndarray:
    """Visible fraction of each object (columns, ``scene.spec.objects`` order) in each pose
    (rows: the start, then each goal's reach) seen from ``view.position``, by ray casting."""
    probe = _probe(scene, reach_fractions)
    return probe.fractions(np.asarray(view.position, float))


@functools.lru_cache(maxsize=64)
def task_view(
    scene: Scene,
    *,
    fov_deg: float = DEFAULT_FOV_DEG,
    aspect: float = DEFAULT_ASPECT,
    usable_width: float = DEFAULT_USABLE_WIDTH,
    margin: float = 0.08,
    context_m: float = 0.15,
    headroom_m: float = 0.0,
    azimuths_deg: tuple[float, ...] = tuple(float(a) for a in range(175, 255, 5)),
    elevations_deg: tuple[float, ...] = tuple(float(e) for e in range(25, 65, 5)),
    distance_factors: tuple[float, ...] = (1.25, 1.0, 1.5),
    reach_fractions: tuple[float, ...] = (0.25, 0.5, 0.75),
    min_visible: float = 0.8,
    tie_tolerance: float = 0.02,
    min_axis_share: float = MIN_AXIS_SHARE,
    min_axis_angle_deg: float = MIN_AXIS_ANGLE_DEG,
) -> TaskView:
    """The viewpoint of ``scene`` that best shows every object and the gripper (module doc);
    ``headroom_m`` keeps that much space above the gripper in frame too (the page's handle).
    Azimuths stay behind the robot's workspace (90-270 deg: moving away from the base moves
    away from the camera).

    Raises :class:`TaskViewError` if no viewpoint keeps everything inside the usable part of
    the frame, or if every one leaves some object less than ``min_visible`` visible.
    """
    if not 0.0 < usable_width <= 1.0 or not 0.0 <= margin < usable_width:
        raise TaskViewError(
            f"task_view: usable_width={usable_width} and margin={margin} must satisfy"
            " 0 <= margin < usable_width <= 1"
        )
    fov = math.radians(fov_deg)
    probe = _probe(scene, reach_fractions)
    grid = _Grid(
        fov=fov, aspect=aspect, usable=usable_width, margin=margin, factors=distance_factors
    )
    frame_pts = _frame_points(scene, probe, context_m=context_m, headroom_m=headroom_m)
    candidates = _candidates(
        probe, frame_pts, task_centre(scene), grid, azimuths_deg, elevations_deg
    )
    if not candidates:
        raise TaskViewError(
            f"scene {scene.name!r}: no viewpoint keeps every object and the gripper inside the"
            f" left {usable_width:.0%} of a {fov_deg:.0f} deg view; widen fov_deg or usable_width"
        )
    chosen = _choose(
        scene,
        probe,
        candidates,
        min_visible=min_visible,
        tie_tolerance=tie_tolerance,
        min_axis_share=min_axis_share,
        min_axis_angle_deg=min_axis_angle_deg,
    )
    return view_at(
        chosen.look,
        distance=chosen.d,
        azimuth_deg=chosen.az,
        elevation_deg=chosen.el,
        fov_rad=fov,
        visible_fraction=_worst_visible(chosen, probe),
        legibility=chosen.legibility,
    )


@dataclass(frozen=True)
class _Grid:
    """The camera's optics and the frame it must fill, and the distances tried per direction."""

    fov: float
    aspect: float
    usable: float
    margin: float
    factors: tuple[float, ...]


def _candidates(
    probe: _Probe,
    frame_pts: np.ndarray,
    centre: np.ndarray,
    grid: _Grid,
    azimuths_deg: tuple[float, ...],
    elevations_deg: tuple[float, ...],
) -> list[_Candidate]:
    """Every direction of the grid where the frame points fit, at each distance factor."""
    candidates: list[_Candidate] = []
    fov, aspect, usable = grid.fov, grid.aspect, grid.usable
    for el in elevations_deg:
        for az in azimuths_deg:
            d_fit = _fit_distance(
                frame_pts, centre, az, el, fov=fov, aspect=aspect, usable=usable, m=grid.margin
            )
            if d_fit is None:
                continue
            for k, factor in enumerate(grid.factors):
                d = d_fit * factor
                look = _look_at(centre, az, el, d, fov=fov, aspect=aspect, usable=usable)
                pos = look + d * _direction(az, el)
                legibility = axis_legibility(pos, az, el, probe.tcp_points)
                candidates.append(_Candidate(az, el, look, pos, d, k, legibility))
    return candidates


def _nearest_default(c: _Candidate) -> tuple[float, int]:
    return (math.hypot(c.az - DEFAULT_AZIMUTH_DEG, c.el - DEFAULT_ELEVATION_DEG), c.k)


def _worst_visible(c: _Candidate, probe: _Probe) -> float:
    """The least visible object's fraction from ``c`` (ray cast once, then remembered)."""
    if c.visible is None:
        c.visible = float(probe.fractions(c.pos).min())
    return c.visible


def _choose(
    scene: Scene,
    probe: _Probe,
    candidates: list[_Candidate],
    *,
    min_visible: float,
    tie_tolerance: float,
    min_axis_share: float,
    min_axis_angle_deg: float,
) -> _Candidate:
    """Among legible views showing every object, the best shown (ties: nearest the default
    direction); if none, the most legible of those showing every object."""

    def worst_visible(c: _Candidate) -> float:
        return _worst_visible(c, probe)

    legible = [
        c
        for c in candidates
        if c.legibility.ok(min_share=min_axis_share, min_angle_deg=min_axis_angle_deg)
    ]
    best = max((worst_visible(c) for c in legible), default=-1.0)
    if best >= min_visible:
        near = [c for c in legible if worst_visible(c) >= best - tie_tolerance]
        return min(near, key=_nearest_default)
    # no legible view shows every object: the most legible of those that do
    seen = [c for c in candidates if worst_visible(c) >= min_visible]
    if not seen:
        c = max(candidates, key=worst_visible)
        raise TaskViewError(
            f"scene {scene.name!r}: the best viewpoint (azimuth {c.az:.0f}, elevation"
            f" {c.el:.0f} deg) leaves only {worst_visible(c):.0%} of some object visible"
            f" (need {min_visible:.0%}); move the objects apart or away from the arm's"
            " reach, or widen the azimuth/elevation grid"
        )

    def score(c: _Candidate) -> float:
        return min(
            min(c.legibility.shares) / max(min_axis_share, 1e-9),
            c.legibility.min_angle_deg / max(min_axis_angle_deg, 1e-9),
        )

    top = max(score(c) for c in seen)
    return min((c for c in seen if score(c) >= top - 0.02), key=_nearest_default)


@dataclass(eq=False)
class _Candidate:
    az: float
    el: float
    look: np.ndarray
    pos: np.ndarray
    d: float
    k: int
    legibility: AxisLegibility
    visible: float | None = None


# -- geometry ----------------------------------------------------------------------------------


def _direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


@functools.lru_cache(maxsize=4096)
def _basis(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera right, up and forward vectors (forward points from the camera to the look-at):
    ``r = f x z / |f x z| = (-sin a, cos a, 0)``, ``u = r x f``."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    ca, sa, ce, se = math.cos(a), math.sin(a), math.cos(e), math.sin(e)
    f = np.array([-ce * ca, -ce * sa, -se])
    r = np.array([-sa, ca, 0.0])
    u = np.array([-se * ca, -se * sa, ce])
    for v in (f, r, u):
        v.flags.writeable = False
    return r, u, f


def _look_at(
    centre: np.ndarray,
    az: float,
    el: float,
    d: float,
    *,
    fov: float,
    aspect: float,
    usable: float,
) -> np.ndarray:
    r, _, _ = _basis(az, el)
    return centre + (1.0 - usable) * d * math.tan(fov / 2) * aspect * r


def _fits(
    pts: np.ndarray,
    centre: np.ndarray,
    az: float,
    el: float,
    d: float,
    *,
    fov: float,
    aspect: float,
    usable: float,
    m: float,
) -> bool:
    look = _look_at(centre, az, el, d, fov=fov, aspect=aspect, usable=usable)
    r, u, f = _basis(az, el)
    rel = pts - (look + d * _direction(az, el))
    depth = rel @ f
    if np.any(depth <= 0.05):
        return False
    t = math.tan(fov / 2)
    x = (rel @ r) / (depth * t * aspect)
    y = (rel @ u) / (depth * t)
    return bool(
        np.all(x >= -1 + m) and np.all(x <= 2 * usable - 1 - m) and np.all(np.abs(y) <= 1 - m)
    )


def _fit_distance(
    pts: np.ndarray,
    centre: np.ndarray,
    az: float,
    el: float,
    *,
    fov: float,
    aspect: float,
    usable: float,
    m: float,
) -> float | None:
    """The smallest distance (to 1 mm) at which ``pts`` fit the usable frame, or None."""
    lo, hi = 0.2, 6.0

    def fits(d: float) -> bool:
        return _fits(pts, centre, az, el, d, fov=fov, aspect=aspect, usable=usable, m=m)

    if not fits(hi):
        return None
    while hi - lo > 1e-3:
        mid = (lo + hi) / 2
        if fits(mid):
            hi = mid
        else:
            lo = mid
    return hi


def _frame_points(
    scene: Scene, probe: _Probe, *, context_m: float, headroom_m: float = 0.0
) -> np.ndarray:
    """What must be in the frame: the objects, the gripper in every pose (and ``headroom_m``
    above it), the robot's base and the table around them (the task points' footprint grown by
    ``context_m``)."""
    top = scene.spec.table.top_z
    above = probe.gripper_points + np.array([0.0, 0.0, headroom_m])
    task = np.vstack([probe.object_corners, probe.gripper_points, above])
    lo, hi = task[:, :2].min(axis=0) - context_m, task[:, :2].max(axis=0) + context_m
    table = np.array([[x, y, top] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    return np.vstack([task, table, [[0.0, 0.0, top]]])


def _tuple3(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


# -- ray casting -------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Samples:
    points: np.ndarray  # (n, 3) world, slightly inside the surface
    normals: np.ndarray  # (n, 3) outward, world
    areas: np.ndarray  # (n,)


class _Probe:
    """The scene posed in each checked configuration, with surface samples of every object."""

    def __init__(self, scene: Scene, reach_fractions: tuple[float, ...]) -> None:
        model = scene.model
        self.model = model
        self.geom_ids = np.array(scene.object_geom_ids, dtype=np.int32)
        qs = reach_configurations(scene, reach_fractions=reach_fractions)
        self.datas: list[mujoco.MjData] = []
        gripper: list[np.ndarray] = []
        for q in qs:
            data = mujoco.MjData(model)
            data.qpos[:7] = q
            data.qpos[7:9] = scene.spec.gripper_open
            mujoco.mj_kinematics(model, data)
            self.datas.append(data)
            gripper.append(data.site_xpos[scene.tcp_site_id])
            gripper.extend(data.xpos[list(scene.finger_body_ids)])
        self.gripper_points = np.array(gripper)
        self.tcp_points = self.gripper_points[::3]  # (TCP, finger, finger) per pose
        rest = self.datas[0]
        self.samples = [_surface_samples(model, rest, int(g)) for g in scene.object_geom_ids]
        self.object_corners = np.vstack(
            [_corners(model, rest, int(g)) for g in scene.object_geom_ids]
        )
        self._pts = np.vstack([s.points for s in self.samples])
        self._normals = np.vstack([s.normals for s in self.samples])
        self._areas = np.concatenate([s.areas for s in self.samples])
        self._owner = np.concatenate([np.full(len(s.areas), i) for i, s in enumerate(self.samples)])

    def fractions(self, eye: np.ndarray) -> np.ndarray:
        """(poses, objects) visible fraction from ``eye``."""
        vec = self._pts - eye
        dist = np.linalg.norm(vec, axis=1)
        vec /= dist[:, None]
        w = self._areas * np.clip(-(self._normals * vec).sum(axis=1), 0.0, None)
        front = w > 0
        vec_f = np.ascontiguousarray(vec[front]).reshape(-1)
        w_f, owner_f = w[front], self._owner[front]
        want = self.geom_ids[owner_f]
        n = int(front.sum())
        total = np.bincount(owner_f, weights=w_f, minlength=len(self.geom_ids))
        geomid = np.empty(n, dtype=np.int32)
        hit = np.empty(n)
        out = np.empty((len(self.datas), len(self.geom_ids)))
        for k, data in enumerate(self.datas):
            mujoco.mj_multiRay(
                self.model, data, eye, vec_f, None, True, -1, geomid, hit, None, n, _RAY_CUTOFF
            )
            seen = np.bincount(
                owner_f, weights=w_f * (geomid == want), minlength=len(self.geom_ids)
            )
            out[k] = seen / np.maximum(total, 1e-12)
        return out


@functools.lru_cache(maxsize=64)
def _probe(scene: Scene, reach_fractions: tuple[float, ...]) -> _Probe:
    return _Probe(scene, reach_fractions)


def _corners(model: mujoco.MjModel, data: mujoco.MjData, gid: int) -> np.ndarray:
    size = model.geom_size[gid]
    if model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_CYLINDER:
        half = np.array([size[0], size[0], size[1]])
    else:
        half = np.array(size[:3])
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    rot = data.geom_xmat[gid].reshape(3, 3)
    return data.geom_xpos[gid] + (signs * half) @ rot.T


def _surface_samples(
    model: mujoco.MjModel, data: mujoco.MjData, gid: int, *, inset: float = 0.97
) -> _Samples:
    """Points on a cylinder's or box's surface (local frame, then world), with normals/areas."""
    size = model.geom_size[gid]
    pts: list[np.ndarray] = []
    nrm: list[np.ndarray] = []
    area: list[float] = []
    if model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_CYLINDER:
        r, h = float(size[0]), float(size[1])
        n_ang, n_h = 16, 4
        for i in range(n_ang):
            a = 2 * math.pi * (i + 0.5) / n_ang
            c, s = math.cos(a), math.sin(a)
            for j in range(n_h):
                z = -h + 2 * h * (j + 0.5) / n_h
                pts.append(np.array([r * c, r * s, z]))
                nrm.append(np.array([c, s, 0.0]))
                area.append(2 * math.pi * r * 2 * h / (n_ang * n_h))
        n_ring, n_cap = 3, 8
        for sign in (1.0, -1.0):
            for j in range(n_ring):
                rho = r * math.sqrt((j + 0.5) / n_ring)
                for i in range(n_cap):
                    a = 2 * math.pi * (i + 0.5 * (j % 2)) / n_cap
                    pts.append(np.array([rho * math.cos(a), rho * math.sin(a), sign * h]))
                    nrm.append(np.array([0.0, 0.0, sign]))
                    area.append(math.pi * r * r / (n_ring * n_cap))
    else:
        half = np.array(size[:3], float)
        n = 4
        for axis in range(3):
            u, v = [k for k in range(3) if k != axis]
            for sign in (1.0, -1.0):
                for i in range(n):
                    for j in range(n):
                        p = np.zeros(3)
                        p[axis] = sign * half[axis]
                        p[u] = half[u] * (-1 + 2 * (i + 0.5) / n)
                        p[v] = half[v] * (-1 + 2 * (j + 0.5) / n)
                        normal = np.zeros(3)
                        normal[axis] = sign
                        pts.append(p)
                        nrm.append(normal)
                        area.append(4 * half[u] * half[v] / (n * n))
    rot = data.geom_xmat[gid].reshape(3, 3)
    local = np.array(pts) * inset
    return _Samples(
        points=data.geom_xpos[gid] + local @ rot.T,
        normals=np.array(nrm) @ rot.T,
        areas=np.array(area),
    )

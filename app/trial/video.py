"""Trial videos: MuJoCo's offscreen renderer (``MUJOCO_GL=egl``) frames written by OpenCV.

``render_live`` runs a trial and films its physics; ``replay`` rebuilds each recorded tick from
its record alone (arm configuration, gripper opening, grasp events), so a trial stored in the
study database can be filmed afterwards. A replayed object rests where the scene put it until
a ``grasped`` event names it, then moves rigidly with the gripper.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import cv2
import mujoco
import numpy as np

from app.robot.scene import Scene
from app.teleop.types import InputSource
from app.trial.config import TrialConfig
from app.trial.errors import TrialError
from app.trial.events import EventKind
from app.trial.records import TickRecord, TrialResult
from app.trial.trial import Trial

os.environ.setdefault("MUJOCO_GL", "egl")


class VideoError(TrialError, RuntimeError):
    """The video could not be written (no OpenGL context, codec missing, bad path)."""


def default_camera() -> mujoco.MjvCamera:
    """A free camera looking at the table from the front-left, as the participant sees it."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = [0.5, 0.1, 0.12]
    cam.distance = 1.45
    cam.azimuth = 200.0
    cam.elevation = -28.0
    return cam


class VideoWriter:
    """Renders ``MjData`` states of one model into an MP4 file (context manager)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        path: str | Path,
        *,
        fps: float = 30.0,
        width: int = 640,
        height: int = 480,
        camera: mujoco.MjvCamera | None = None,
    ) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        try:
            self.renderer = mujoco.Renderer(model, height=height, width=width)
        except Exception as exc:
            raise VideoError(
                f"cannot create an offscreen OpenGL context ({exc}); set MUJOCO_GL=egl"
                " (needs libegl1) or MUJOCO_GL=osmesa (needs libosmesa6)"
            ) from exc
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self.camera = camera or default_camera()
        fourcc = cv2.VideoWriter_fourcc(*"mp4v")
        self.writer = cv2.VideoWriter(str(self.path), fourcc, float(fps), (width, height))
        if not self.writer.isOpened():
            self.renderer.close()
            raise VideoError(f"OpenCV cannot write {self.path} (mp4v codec)")
        self.frames = 0

    def add(self, data: mujoco.MjData) -> None:
        self.renderer.update_scene(data, camera=self.camera)
        rgb = self.renderer.render()
        self.writer.write(np.ascontiguousarray(rgb[:, :, ::-1]))
        self.frames += 1

    def close(self) -> None:
        self.writer.release()
        self.renderer.close()

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def render_live(
    config: TrialConfig,
    input_source: InputSource,
    path: str | Path,
    *,
    seed: int = 0,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
) -> tuple[TrialResult, int]:
    """Run a trial and film it; returns the result and the number of frames written."""
    trial = Trial(config, input_source, seed=seed)
    every = max(1, round(config.rate_hz / fps))
    with VideoWriter(
        trial.sim.model, path, fps=config.rate_hz / every, width=width, height=height
    ) as video:
        video.add(trial.sim.data)
        while not trial.done:
            trial.tick()
            if trial.ticks % every == 0 or trial.done:
                video.add(trial.sim.data)
        frames = video.frames
    return trial.result(), frames


def replay_states(
    scene: Scene, records: Sequence[TickRecord], *, every: int = 1
) -> Iterator[tuple[TickRecord, mujoco.MjData]]:
    """Rebuild the scene at every ``every``-th record (and the last) from the records alone."""
    model = scene.model
    data = mujoco.MjData(model)
    mujoco.mj_resetData(model, data)
    data.qpos[:7] = scene.start_q
    mujoco.mj_forward(model, data)
    rest = [data.qpos[a : a + 7].copy() for a in scene.object_qpos_addr]
    names = scene.object_names
    attached: tuple[int, np.ndarray, np.ndarray] | None = None  # object, offset, rotation
    site = scene.tcp_site_id
    for i, rec in enumerate(records):
        data.qpos[:7] = rec.q
        data.qpos[7:9] = rec.gripper
        for k, addr in enumerate(scene.object_qpos_addr):
            data.qpos[addr : addr + 7] = rest[k]
        mujoco.mj_kinematics(model, data)
        for event in rec.events:
            if event.kind is EventKind.GRASPED and event.obj in names:
                k = names.index(event.obj)
                rot = data.site_xmat[site].reshape(3, 3).copy()
                obj = rest[k][:3]
                attached = (k, rot.T @ (obj - data.site_xpos[site]), rot)
        if attached is not None:
            k, offset, rot0 = attached
            rot = data.site_xmat[site].reshape(3, 3)
            addr = scene.object_qpos_addr[k]
            data.qpos[addr : addr + 3] = data.site_xpos[site] + rot @ offset
            q_obj = np.zeros(4)
            mujoco.mju_mat2Quat(q_obj, (rot @ rot0.T).reshape(9))
            q_rest = rest[k][3:]
            q_new = np.zeros(4)
            mujoco.mju_mulQuat(q_new, q_obj, q_rest)
            data.qpos[addr + 3 : addr + 7] = q_new
            mujoco.mj_kinematics(model, data)
        if i % every == 0 or i == len(records) - 1:
            yield rec, data


def replay(
    scene: Scene,
    records: Sequence[TickRecord],
    path: str | Path,
    *,
    rate_hz: float = 100.0,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    on_frame: Callable[[TickRecord, mujoco.MjData], None] | None = None,
) -> int:
    """Film recorded ticks; returns the number of frames. ``on_frame`` sees each filmed state."""
    if not records:
        raise VideoError("no records to replay")
    every = max(1, round(rate_hz / fps))
    with VideoWriter(scene.model, path, fps=rate_hz / every, width=width, height=height) as video:
        for rec, data in replay_states(scene, records, every=every):
            if on_frame is not None:
                on_frame(rec, data)
            video.add(data)
        return video.frames

"""``LiveView``: the participant tab's 3-D view of the current run, drawn by its own loop.

The control thread hands over a snapshot of the run's body poses after each tick that moved
something (``snap``); the render loop (``step``, up to ``render_hz``) sends the newest snapshot
to the tab, but only while the view shows that run (``frame_key``): never an earlier run's end
pose on the next ready screen, whose preview (``draw_preview``) shows the next run's start.
The render loop also carries the page's small live notices (a missed grasp, the handle following
the keys).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from app.robot import BodyPoses, Scene
from study.server.inputs import ParticipantInput
from study.server.intent_cue import IntentGoals, ring_opacity
from study.server.live.texts import MISSED_GRASP
from study.server.loop import PacedLoop
from study.server.participant import ParticipantPage
from study.server.scene import SceneView, frame_scene
from study.session import TrialRun

LOGGER = logging.getLogger("study.server.live")

MOVED_M = 2e-4
"""Bodies that moved less than this (m; rotation-matrix entries by 10x this) since the last
frame sent are not re-sent: an arm holding still, which jitters by micrometres under its
controller, sends no scene updates (0.2 mm is a tenth of a pixel at the task view)."""


Intent = tuple[int, float]
"""The robot's intent at a tick: (index of its predicted goal G*, its confidence)."""


@dataclass(frozen=True)
class Snapshot:
    """The poses (and the robot's intent, ``None`` before its first tick) after a tick that
    moved something or changed the shown intent; ``seq`` counts them per view."""

    key: object
    seq: int
    poses: BodyPoses
    intent: Intent | None = None


class LiveView:
    """One session's scene view and render loop (see module docstring)."""

    def __init__(
        self,
        *,
        code: str,
        render_hz: float,
        tab: Callable[[], tuple[ParticipantPage | None, ParticipantInput | None]],
    ) -> None:
        self.code = code
        self._tab = tab
        """The bound tab and the participant's input now (``None`` when there is none)."""
        self.render_hz = render_hz
        self.view: SceneView | None = None
        self._view_key: tuple[int, str, bool] | None = None
        self._scene: Scene | None = None
        self._snapshot: Snapshot | None = None
        self._frame_key: object = None
        self._rendered_seq = -1
        self._lock = threading.Lock()
        """One frame at a time: the render loop's against a preview draw or a view rebuild."""
        self._loop: PacedLoop | None = None
        self.missed_grasp = threading.Event()
        """Set by the control thread; the render loop tells the participant."""

    # ---- control thread ------------------------------------------------------------------------
    def snap(self, run: TrialRun, poses: BodyPoses, intent: Intent | None = None) -> None:
        """Keep ``run``'s poses and the robot's ``intent`` for the render loop if something
        moved, or the shown intent changed, since the last."""
        last = self._snapshot
        if (
            last is not None
            and last.key is run
            and float(np.max(np.abs(poses.xpos - last.poses.xpos))) < MOVED_M
            and float(np.max(np.abs(poses.xmat - last.poses.xmat))) < 10 * MOVED_M
            and _same_intent(last.intent, intent)
        ):
            return
        self._snapshot = Snapshot(run, 0 if last is None else last.seq + 1, poses, intent)

    # ---- page thread (the caller holds LiveSession's lock) ----------------------------------------
    def follow(self, run: TrialRun) -> None:
        """From now on the render loop sends ``run``'s snapshots (and only those)."""
        self._frame_key = run

    def start(self) -> None:
        if self._loop is None or not self._loop.alive:
            self._loop = PacedLoop(self.step, rate_hz=self.render_hz, name=f"render-{self.code}")
            self._loop.start()

    def stop(self) -> None:
        if self._loop is not None:
            self._loop.stop()
            self._loop = None

    def drop(self) -> None:
        """The tab went away: the next one builds its own view."""
        self.view = None
        self._view_key = None

    def ensure(
        self, page: ParticipantPage, scene: Scene, model: mujoco.MjModel, *, intent: bool
    ) -> SceneView:
        """The tab's view of ``scene``, with the intent ring if ``intent``: rebuilt (and the
        camera framed on the task) when the tab, the scene or the display changed."""
        key = (page.client.client_id, str(scene.name), intent)
        if self.view is None or self._view_key != key:
            page.client.scene.reset()
            self.view = SceneView(
                page.client,
                model,
                table_top=scene.spec.table.top_z,
                goals=IntentGoals.of_scene(scene) if intent else None,
            )
            self._view_key = key
            self._scene = scene
            self._rendered_seq = -1
            frame_scene(page.client.camera, scene)
        return self.view

    def draw_preview(
        self,
        page: ParticipantPage,
        scene: Scene,
        model: mujoco.MjModel,
        poses: BodyPoses,
        *,
        intent: bool,
    ) -> None:
        """Show ``scene`` at its start state (the render loop keeps off it)."""
        with self._lock:
            self._frame_key = ("preview", str(scene.name))
            view = self.ensure(page, scene, model, intent=intent)
            view.render(poses.xpos, poses.xmat, gripper=poses.gripper)

    def reframe(self, page: ParticipantPage | None) -> None:
        """Put the tab's camera back on the task view."""
        if page is not None and self._scene is not None:
            frame_scene(page.client.camera, self._scene)

    # ---- render thread -----------------------------------------------------------------------
    def step(self) -> None:
        """One render-loop period: notices, the newest frame, the handle following the keys."""
        page, source = self._tab()
        view, snap = self.view, self._snapshot
        if self.missed_grasp.is_set():
            self.missed_grasp.clear()
            if page is not None:
                page.notify(MISSED_GRASP)
        if view is not None and snap is not None and snap.seq != self._rendered_seq:
            with self._lock:
                if snap.key is self._frame_key and view is self.view:
                    self._rendered_seq = snap.seq
                    try:
                        poses = snap.poses
                        view.render(
                            poses.xpos, poses.xmat, gripper=poses.gripper, intent=snap.intent
                        )
                    except Exception:  # a tab closing mid-frame; the next tab gets the next
                        LOGGER.debug("render failed", exc_info=True)
        if page is not None and source is not None:
            # the handle follows the keys (absolute), or the gripper when let go (relative)
            at = source.handle_position(None if snap is None else snap.poses.gripper)
            if at is not None:
                page.move_gizmo(at)


def shows_intent(extra: Mapping[str, object]) -> bool:
    """Whether a trial shows the robot's intent: its mode's ``intent`` option
    (``study.protocol.model.INTENT_DISPLAYS``), carried in the trial config's ``extra``."""
    return extra.get("intent", "none") != "none"


def _same_intent(a: Intent | None, b: Intent | None) -> bool:
    """Whether intents ``a`` and ``b`` draw the same ring (same goal, same quantised opacity)."""
    if a is None or b is None:
        return a is b
    return a[0] == b[0] and ring_opacity(a[1]) == ring_opacity(b[1])

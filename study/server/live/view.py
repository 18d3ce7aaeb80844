"""``LiveView``: the participant tab's 3-D view of the current run, drawn by its own loop.

The control thread hands over a snapshot of the run's body poses after each tick that moved
something (``snap``); the render loop (``step``, up to ``render_hz``, and no faster than the
tab draws: :mod:`study.server.draw_rate`) sends the newest snapshot to the tab, but only while
the view shows that run (``frame_key``): never an earlier run's end pose on the next ready
screen, whose preview (``draw_preview``) shows the next run's start.
The render loop also carries the page's live notices (the held one of
:mod:`study.server.live.notices`: the input held past the reach, a finger resting on an object,
a missed grasp; and ten seconds left), the trial screen's countdown and the handle following
the keys.
The view from above (:class:`study.server.inset.InsetLoop`) draws the same snapshots in a thread
of its own.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from app.robot import BodyPoses, Scene
from app.teleop.participant_input import ParticipantInput
from study.server.draw_rate import Pacer, inset_hz, scene_hz
from study.server.inset import INSET_HZ, InsetJob, InsetLoop
from study.server.intent_cue import IntentGoals, ring_opacity
from study.server.live.notices import HeldNotices
from study.server.live.texts import TIME_WARNING, TIME_WARNING_S
from study.server.loop import PacedLoop
from study.server.page_scene import SceneView, frame_scene, reach_footprint
from study.server.participant_page import ParticipantPage
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
        self._pacer = Pacer()
        self._handle_pacer = Pacer()
        """Scene updates and the handle's moves no faster than the tab draws them
        (:mod:`study.server.draw_rate`)."""
        self._lock = threading.Lock()
        """One frame at a time: the render loop's against a preview draw or a view rebuild."""
        self._loop: PacedLoop | None = None
        self._model: mujoco.MjModel | None = None
        self._azimuth = 225.0
        self.inset: InsetLoop | None = None
        self.notices = HeldNotices()
        """Stamped by the control thread; the render loop holds the notice they call for."""
        self._notice_shown: str | None = None
        self._warned: object = None

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
        if self.inset is None or (not self.inset.alive and self.inset.failed is None):
            self.inset = InsetLoop(
                name=f"inset-{self.code}", job=self._inset_job, sink=self._inset_frame
            ).start()

    def stop(self) -> None:
        if self._loop is not None:
            self._loop.stop()
            self._loop = None
        if self.inset is not None:
            self.inset.stop()

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
                reach=reach_footprint(scene.reach.lo, scene.reach.hi, scene.spec.table),
            )
            self._view_key = key
            self._scene = scene
            self._rendered_seq = -1
            view = frame_scene(page.client.camera, scene)
            self._azimuth = 225.0 if view is None else view.azimuth_deg
        self._model = model
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
        if page is not None:
            self._notices(page)
        now = time.monotonic()
        hz = scene_hz(None if page is None else page.draw_hz, render_hz=self.render_hz)
        if (
            view is not None
            and snap is not None
            and snap.seq != self._rendered_seq
            and self._pacer.due(now, hz)
        ):
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
        if page is not None and source is not None and self._handle_pacer.due(now, hz):
            # the handle follows the keys (absolute), or the gripper when let go (relative), at
            # the scene's pace (a key's move not yet sent waits for the next due step)
            at = source.handle_position(None if snap is None else snap.poses.gripper)
            if at is not None:
                page.move_gizmo(at)

    def _notices(self, page: ParticipantPage) -> None:
        """The countdown, ten seconds left, the grasp button's state (greyed while the gripper
        is closed) and the held notice (:mod:`study.server.live.notices`; taken down when
        nothing calls for it, or when the run is not live)."""
        run = self._frame_key if isinstance(self._frame_key, TrialRun) else None
        live = run is not None and not run.over and not run.paused
        if live and run is not None:
            left = run.config.time_limit_s - run.trial.t
            page.set_time_left(left)
            if left <= TIME_WARNING_S and self._warned is not run:
                self._warned = run
                if run.config.time_limit_s > 2 * TIME_WARNING_S:
                    page.notify(TIME_WARNING)
        page.show_gripper_closed(live and run is not None and run.trial.task.gripper_closed)
        text = self.notices.text(time.monotonic(), live=live)
        if text != self._notice_shown:
            self._notice_shown = text
            page.hold_notice(text)

    def clear_notices(self, page: ParticipantPage | None) -> None:
        """The run ended or the tab changed: no held notice stays up."""
        self._notice_shown = None
        if page is not None:
            page.hold_notice(None)

    # ---- inset thread ----------------------------------------------------------------------
    def _inset_job(self) -> InsetJob | None:
        """What the view from above should show now (None: the page shows no such picture)."""
        page = self._tab()[0]
        snap, scene, model = self._snapshot, self._scene, self._model
        if page is None or not page.shows_inset or snap is None or scene is None:
            return None
        if model is None or snap.key is not self._frame_key:
            return None
        return InsetJob(
            key=(snap.seq, page.client.client_id, page.screen),
            scene=scene,
            model=model,
            view_azimuth_deg=self._azimuth,
            poses=snap.poses,
            words=page.words,
            most_hz=inset_hz(page.draw_hz, most_hz=INSET_HZ),
        )

    def _inset_frame(self, jpeg: bytes) -> None:
        page = self._tab()[0]
        if page is not None:
            page.show_inset(jpeg)


def shows_intent(extra: Mapping[str, object]) -> bool:
    """Whether a trial shows the robot's intent: its mode's ``intent`` option
    (``study.protocol.model.INTENT_DISPLAYS``), carried in the trial config's ``extra``."""
    return extra.get("intent", "none") != "none"


def _same_intent(a: Intent | None, b: Intent | None) -> bool:
    """Whether intents ``a`` and ``b`` draw the same ring (same goal, same quantised opacity)."""
    if a is None or b is None:
        return a is b
    return a[0] == b[0] and ring_opacity(a[1]) == ring_opacity(b[1])

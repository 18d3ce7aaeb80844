"""``TeleopHandle``: the handle a participant drags to steer the gripper, on their tab's scene.

The handle floats :data:`HANDLE_OFFSET_M` above the point the gripper is sent to, with a thin
stem down to it; its arrows keep :data:`HANDLE_PX` on the screen whatever the zoom. Every pose
update the tab sends is checked (``page_inputs.parse_position``) and passed on as a target, in
arrival order; letting go is reported too.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Callable

import numpy as np
import viser

from study.server.page_inputs import InputRejected, parse_position

HANDLE_OFFSET_M = 0.12
"""The handle floats this far above the point the gripper is sent to (a thin stem joins them),
so that near a grasp it never covers the object; its arrows point away from the task camera
(``app.robot.task_view`` keeps the camera behind the robot), upward on the screen."""
HANDLE_PX = 150.0
"""Length of the handle's arrows on the screen (pixels, whatever the zoom)."""
HANDLE_LINE_PX = 5.0


class TeleopHandle:
    """The handle on one tab's scene (``lock``: the page's; ``reject(problem, notify)``: how the
    page records an ignored input)."""

    def __init__(
        self,
        client: viser.ClientHandle,
        *,
        lock: threading.RLock,
        reject: Callable[[str, bool], None],
    ) -> None:
        self.client = client
        self._lock = lock
        self._reject = reject
        self.gizmo: viser.TransformControlsHandle | None = None
        self._stem: list[object] = []
        self.dragging = False
        """True while the participant holds the handle with the mouse."""

    def add(
        self,
        position: np.ndarray,
        *,
        on_target: Callable[[np.ndarray], None],
        on_release: Callable[[], None] | None = None,
    ) -> viser.TransformControlsHandle:
        """The transform handle, :data:`HANDLE_OFFSET_M` above the target ``position``, with a
        stem down to it; every pose update sends the target (the handle's position minus the
        offset) to ``on_target``, and letting go of it calls ``on_release``."""
        offset = np.array([0.0, 0.0, HANDLE_OFFSET_M])
        scene = self.client.scene
        with self._lock:
            self.remove()
            gizmo = scene.add_transform_controls(
                "/handle",
                scale=HANDLE_PX,
                fixed=True,
                line_width=HANDLE_LINE_PX,
                disable_rotations=True,
                depth_test=False,
                opacity=0.9,
                position=tuple(np.asarray(position, float) + offset),
            )
            self.gizmo = gizmo
            # children move with the handle in the browser while it is dragged
            self._stem = [
                scene.add_cylinder(
                    "/handle/stem",
                    radius=0.0025,
                    height=HANDLE_OFFSET_M,
                    color=(60, 60, 70),
                    position=(0.0, 0.0, -HANDLE_OFFSET_M / 2),
                ),
                scene.add_icosphere(
                    "/handle/tip", radius=0.006, color=(60, 60, 70), position=tuple(-offset)
                ),
            ]

        # async: runs on viser's event loop in arrival order (thread-pool callbacks may run
        # out of order, and a stale pose must never overwrite a newer one); ``on_target`` only
        # takes a lock. A rejection (notice + store event) and a release go to a worker thread.
        @gizmo.on_update
        async def _(event: viser.TransformControlsEvent) -> None:
            phase = getattr(event, "phase", "update")
            if phase != "update":
                self.dragging = phase == "start"
                if phase == "end" and on_release is not None:
                    asyncio.get_running_loop().run_in_executor(None, on_release)
                return  # the same pose as the update before it
            try:
                on_target(parse_position(gizmo.position) - offset)
            except InputRejected as exc:
                asyncio.get_running_loop().run_in_executor(None, self._reject, str(exc), False)

        return gizmo

    def move(self, position: np.ndarray) -> None:
        """Put the handle over the target ``position``."""
        with self._lock:
            if self.gizmo is not None:
                self.gizmo.position = tuple(
                    np.asarray(position, float) + np.array([0.0, 0.0, HANDLE_OFFSET_M])
                )

    def show(self, visible: bool) -> None:
        with self._lock:
            if self.gizmo is not None:
                self.gizmo.visible = visible

    def remove(self) -> None:
        with self._lock:
            self.dragging = False
            for h in [*self._stem, self.gizmo]:
                if h is not None:
                    with contextlib.suppress(Exception):
                        h.remove()  # type: ignore[attr-defined]
            self.gizmo, self._stem = None, []

"""The robot's intent on the participant page: a neutral ring around the predicted object.

A mode with ``intent = "goal"`` (``study.protocol.model.INTENT_DISPLAYS``) shows the participant
which object the robot is assisting toward, the goal ``G*`` its policy ``P`` heads for. Per
frame, from the trial's last tick: ``predicted`` (the index ``k`` of ``G*`` among the scene's
objects) and the confidence ``c`` the arbitration used. The ring lies flat on the table around
object ``k``'s current position (it follows an object that was pushed), with

    opacity = OPACITY_MAX * c_q,   c_q = round(c / STEP) * STEP,   shown only when c_q >= SHOW_FROM,

so a robot unsure of its goal shows nothing, and a confident one a clear ring. Quantising ``c``
and moving the ring only when the object moved more than ``MOVED_M`` keep the traffic to a few
small messages per change in prediction (none while nothing changes).

Blinding: the ring is one colour (charcoal grey, on every object and in every condition: no
green/red semantics), carries no text, and its node name is geometric (``/cue/ring``); whether
a run shows it follows from the mode, whose name never reaches the browser. A mode without the
display creates no node at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

RING_NODE = "/cue/ring"
RING_COLOR = (40, 40, 50)
"""Charcoal: neutral (no right/wrong hue), unlike any object's colour, and it stands out on the
table, which the page's lights draw pale (a near-white ring was barely visible there)."""
OPACITY_MAX = 0.85
STEP = 0.1
SHOW_FROM = 0.2
MOVED_M = 0.002
GAP_M = 0.012
"""Clearance between the object's footprint and the ring's inner edge."""
INNER = 0.72
"""Inner over outer radius: a band about 1.8 cm wide around the paper scenes' objects."""
SEGMENTS = 48


def ring_mesh(*, inner: float, outer: float, segments: int = SEGMENTS) -> tuple[Any, Any]:
    """A flat annulus in the xy plane around the origin: ``(vertices (2s, 3), faces (2s, 3))``."""
    if not 0.0 < inner < outer:
        raise ValueError(f"ring_mesh: need 0 < inner < outer, got {inner}, {outer}")
    a = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    vertices = np.vstack([inner * ring, outer * ring]).astype(np.float32)
    i = np.arange(segments)
    j = (i + 1) % segments
    faces = np.vstack(
        [np.stack([i, segments + i, segments + j], 1), np.stack([i, segments + j, j], 1)]
    ).astype(np.uint32)
    return vertices, faces


@dataclass(frozen=True)
class IntentGoals:
    """What the ring needs of a scene: each object's body id (index ``k`` = goal ``k``), its
    footprint radius (m), and the table top's height (m)."""

    body_ids: tuple[int, ...]
    radii: tuple[float, ...]
    table_top: float

    @classmethod
    def of_scene(cls, scene: Any) -> IntentGoals:
        """From an ``app.robot.scene.Scene`` (its objects in goal order)."""
        return cls(
            body_ids=tuple(int(b) for b in scene.object_body_ids),
            radii=tuple(float(o.footprint_radius) for o in scene.spec.objects),
            table_top=float(scene.spec.table.top_z),
        )


def ring_opacity(confidence: float) -> float:
    """The ring's opacity for ``confidence`` (0 = not shown): see the module docstring."""
    if not np.isfinite(confidence):
        return 0.0
    c = round(min(max(float(confidence), 0.0), 1.0) / STEP) * STEP
    return 0.0 if c < SHOW_FROM - 1e-9 else round(OPACITY_MAX * c, 3)


class IntentCue:
    """The ring on one participant's scene (``scene_api``: a viser ``SceneApi``)."""

    def __init__(self, scene_api: Any, goals: IntentGoals) -> None:
        self.goals = goals
        # one mesh of outer radius 1, scaled per object in x and y
        vertices, faces = ring_mesh(inner=INNER, outer=1.0)
        self._ring = scene_api.add_mesh_simple(
            RING_NODE,
            vertices,
            faces,
            color=RING_COLOR,
            opacity=OPACITY_MAX,
            side="double",
            cast_shadow=False,
            receive_shadow=False,
            visible=False,
        )
        self._shown: tuple[int, float] | None = None  # (goal, opacity) now on the page
        self._at: np.ndarray | None = None
        self.updates = 0
        """How many times the ring changed (for tests and the page benchmark)."""
        self.suppressed = False
        """True keeps the ring hidden whatever the prediction: benchmarks/page_fps.py compares
        frame rates with and without it within one run."""

    @property
    def visible_goal(self) -> int | None:
        """The goal index the ring is drawn around, None while it is hidden."""
        return None if self._shown is None else self._shown[0]

    def update(self, xpos: np.ndarray, predicted: int, confidence: float) -> None:
        """Place the ring for goal ``predicted`` at confidence ``confidence``; body positions
        ``xpos (nbody, 3)``. Sends nothing when nothing visible changed."""
        opacity = 0.0 if self.suppressed else ring_opacity(confidence)
        if opacity <= 0.0 or not 0 <= predicted < len(self.goals.body_ids):
            if self._shown is not None:
                self._ring.visible = False
                self._shown = None
                self.updates += 1
            return
        at = np.asarray(xpos, float)[self.goals.body_ids[predicted], :2]
        same_goal = self._shown is not None and self._shown[0] == predicted
        moved = self._at is None or float(np.max(np.abs(at - self._at))) > MOVED_M
        if not same_goal or moved:
            # scaled so that the inner edge clears the footprint by GAP_M
            s = (self.goals.radii[predicted] + GAP_M) / INNER
            self._ring.scale = (s, s, 1.0)
            self._ring.position = (float(at[0]), float(at[1]), self.goals.table_top + 0.0015)
            self._at = at
        if self._shown is None or self._shown[1] != opacity:
            self._ring.opacity = opacity
        if self._shown is None:
            self._ring.visible = True
        if self._shown != (predicted, opacity) or moved:
            self.updates += 1
        self._shown = (predicted, opacity)

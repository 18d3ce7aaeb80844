"""The participant's two inputs as one ``InputSource``: the gizmo's handle and held keys.

The page and the simulated participants drive the same device: ``set_target`` (a handle pose
while it is dragged), ``let_go`` (the drag ended), ``key_down``/``key_up``, ``request_grasp``;
the page draws the handle where ``handle_position`` says. Grasp requests from the button, the
G key, or either source are merged. The time from a handle pose arriving (``set_target``) to
the tick whose command uses it is recorded in ``latencies_s`` (the server benchmark reports it).

Two mappings (``mapping``, the protocol's ``[control] input_mapping``):

- ``absolute`` (the paper's interface): the handle is the gripper's target. A pose that arrived
  since the last tick wins; otherwise held keys move the last clamped target
  (``KeyboardInput``, a fixed speed while held) and the handle follows, so the two never
  fight. A robot pulling the gripper elsewhere cannot move the target: the user's ``U`` keeps
  pulling toward it.
- ``relative`` (a rate / clutch mapping): the input moves the gripper from where it is. The
  device keeps a pending displacement ``d``: each handle pose adds its displacement since the
  last one (the first of a drag since where the handle was drawn), held keys add ``speed dt``
  per tick (a velocity of the gripper); each tick the target is ``h + d``, then the part
  ``s = d (1 - exp(-dt k))`` is spent, ``d <- d - s``, ``h <- h + s``, with ``k`` the IK gain
  (``app.teleop.ik_step.GAIN_PER_S``). ``h`` is where the input holds the gripper. While the
  robot moves the gripper too (``alpha > 0``), ``h`` is the gripper's position: a robot that
  moves the gripper carries the target along, nothing pulls it back, and the user has to keep
  moving against the robot. While the user alone moves it (``alpha = 0``: practice, an
  unassisted or a still unsure robot), ``h`` moves by what the input spends and follows the
  gripper only when something takes it more than :data:`HOLD_M` away (a knock, a push
  against an object), ``h <- ee + clip(h - ee, HOLD_M)``: with ``h = ee`` there, the arm's own
  tracking error (under a millimetre at rest) was commanded again every tick and the gripper
  crept away while the user held still (36 mm in 30 s after a drag; now none), and a 12 cm
  drag ended 8 mm short (now 4 mm). Alone, the arm moves the gripper toward the target at
  ``k d`` -- the rate at which ``d`` is spent -- so the gripper travels the input's
  displacement, ``1/k`` seconds behind. When a drag ends the handle returns to the gripper
  (``handle_position``), and follows it while not dragged. The robot predicts the user's goal
  from the path their own input traced -- the gripper's start plus every displacement they
  gave, clamped to the reach (``TeleopCommand.path``) -- not from the target, which the robot's
  own motion carries along (a wrong prediction would then confirm itself).

While ``frozen`` (a pause: by the experimenter, a lost tab, a fault) every input is refused
with :class:`InputFrozen` and nothing is queued, so nothing done during a pause is applied
after it; ``freeze()`` also lets go of held keys and drops pending grasps, poses and
displacement.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque

import numpy as np

from app.errors import AppError
from app.teleop.errors import TeleopError
from app.teleop.gizmo import GizmoInput, checked_position
from app.teleop.ik_step import GAIN_PER_S
from app.teleop.keyboard import KEY_SPEED_M_S, KeyboardInput
from app.teleop.types import TeleopCommand, TrialObservation

INPUT_MAPPINGS = ("absolute", "relative")
"""How the handle and keys map to the gripper (the module docstring)."""

HOLD_M = 0.005
"""Relative mapping: the gripper may be this far from where the input holds it before the hold
follows it (more than the arm's tracking error at rest, under 1 mm, and its lag in a drag;
small beside the robot's own motion)."""

HANDLE_STEP_M = 0.001
"""In the relative mapping the handle is redrawn on the gripper once it is this far off."""


class InputFrozen(AppError, RuntimeError):
    """An input arrived while the trial is paused; it was not applied."""


class ParticipantInput:
    """Gizmo + keyboard, thread-safe: UI callbacks write, the control loop reads."""

    def __init__(
        self,
        *,
        start_target: np.ndarray | None = None,
        key_speed_m_s: float = KEY_SPEED_M_S,
        mapping: str = "absolute",
    ) -> None:
        if mapping not in INPUT_MAPPINGS:
            raise TeleopError(f"mapping: one of {', '.join(INPUT_MAPPINGS)}, got {mapping!r}")
        self.mapping = mapping
        self.relative = mapping == "relative"
        self.gizmo = GizmoInput(start_target)
        self.keyboard = KeyboardInput(speed=key_speed_m_s)
        self._lock = threading.Lock()
        self._seq = 0
        self._used = 0
        self._arrival: float | None = None
        self._grasp = False
        self._frozen = False
        # relative mapping: pending displacement, the handle's last position, dragging or not
        self._pending = np.zeros(3)
        self._hold: np.ndarray | None = None  # where the gripper is held (relative mapping)
        self._moved = np.zeros(3)  # displacement given since the last tick, for the path
        self._path: np.ndarray | None = None
        self._handle: np.ndarray | None = (
            None if start_target is None else checked_position(start_target)
        )
        self._dragging = False
        self.latencies_s: deque[float] = deque(maxlen=20000)
        self.last_target: np.ndarray | None = None
        self.key_moved = threading.Event()
        """Set when held keys moved the target (the UI moves the gizmo to ``last_target``)."""

    # -- pause -----------------------------------------------------------------------------------
    @property
    def frozen(self) -> bool:
        return self._frozen

    def freeze(self) -> None:
        """Refuse input until ``thaw``; drop what is pending (held keys, grasps, poses)."""
        with self._lock:
            self._frozen = True
            self._grasp = False
            self._used = self._seq
            self._pending[:] = 0.0
            self._moved[:] = 0.0
            self._dragging = False
        self.keyboard.release_all(discard=True)

    def thaw(self) -> None:
        with self._lock:
            self._frozen = False

    def _check(self, what: str) -> None:
        if self._frozen:
            raise InputFrozen(f"{what} while paused: not applied")

    # -- UI side -------------------------------------------------------------------------------
    def set_target(self, target: np.ndarray) -> None:
        """A handle pose (3,) while it is dragged; a non-finite one raises
        ``InvalidTargetError``, state unchanged. Absolute: the gripper's target; relative: its
        displacement since the last pose moves the gripper."""
        self._check("handle moved")
        if not self.relative:
            self.gizmo.set_target(target)
            with self._lock:
                self._seq += 1
                self._arrival = time.perf_counter()
            return
        pose = checked_position(target)
        with self._lock:
            if self._handle is not None:
                self._pending += pose - self._handle
                self._moved += pose - self._handle
            self._handle = pose
            self._dragging = True
            self._seq += 1
            self._arrival = time.perf_counter()

    def let_go(self) -> None:
        """The drag ended (always accepted). Relative: the handle goes back to the gripper."""
        with self._lock:
            self._dragging = False

    def place(self, position: np.ndarray) -> None:
        """The handle is put at ``position`` (3,) without a drag: absolute, the target is there;
        relative, nothing moves and nothing is pending."""
        if not self.relative:
            self.set_target(position)
            return
        pose = checked_position(position)
        with self._lock:
            self._handle = pose
            self._pending[:] = 0.0
            self._dragging = False

    def resume_at(self, gripper: np.ndarray) -> np.ndarray:
        """Where the handle goes when a pause ends, the ``gripper`` (3,) where the pause left it.
        Absolute: on the participant's own target, unchanged -- while the robot helped, or
        wrongly took over, it moved the gripper, never their input, and the prediction must go
        on reading what they asked for, not where the robot was going. Relative: on the
        gripper, nothing pending (``place``). Before the run's first tick: on the gripper.
        Absolute, the handle's last pose wins over the last tick's target: a pose that arrived
        just before the pause is what the next tick commands, so the handle is drawn there."""
        if self.relative or self.last_target is None:
            self.place(gripper)
            return checked_position(gripper)
        pose = self.gizmo.target
        return self.last_target.copy() if pose is None else pose

    def handle_position(self, gripper: np.ndarray | None) -> np.ndarray | None:
        """Where the page should draw the handle now, or ``None`` to leave it. Absolute: where
        held keys moved the target. Relative: on the ``gripper`` while not dragged."""
        if not self.relative:
            if not self.key_moved.is_set():
                return None
            self.key_moved.clear()
            return self.last_target
        if gripper is None:
            return None
        at = np.asarray(gripper, dtype=float)
        with self._lock:
            if self._dragging:
                return None
            if self._handle is not None and np.abs(at - self._handle).max() < HANDLE_STEP_M:
                return None
            self._handle = at.copy()
            return self._handle.copy()

    def key_down(self, key: str) -> None:
        """A steering or grasp key went down (see ``app.teleop.keyboard.KEYMAP``)."""
        self._check(f"key {key!r} pressed")
        self.keyboard.hold(key)

    def key_up(self, key: str) -> None:
        """A key went up; always accepted (a key released during a pause is simply up)."""
        self.keyboard.release(key)
        if self._frozen:
            self.keyboard.release_all(discard=True)

    def request_grasp(self) -> None:
        self._check("grasp")
        with self._lock:
            self._grasp = True

    @property
    def dragging(self) -> bool:
        """A drag of the handle is under way (relative mapping)."""
        return self._dragging

    # -- control loop side -----------------------------------------------------------------------
    def command(self, obs: TrialObservation) -> TeleopCommand:
        with self._lock:
            fresh = self._seq != self._used
            self._used = self._seq
            arrival = self._arrival
            grasp, self._grasp = self._grasp, False
        if fresh and arrival is not None:
            self.latencies_s.append(time.perf_counter() - arrival)
        if self.relative:
            target, path, asked = self._relative(obs)
            self.last_target = target
            return TeleopCommand(target, bool(grasp or asked), path=path)
        from_gizmo = self.gizmo.command(obs)
        keys_moving = self.keyboard.moving
        from_keys = self.keyboard.command(obs)
        if fresh:
            target = from_gizmo.target
        elif keys_moving:
            target = from_keys.target
            self.gizmo.set_target(target)
            self.key_moved.set()
        else:
            target = from_gizmo.target
        self.last_target = np.array(target, dtype=float)
        return TeleopCommand(target, bool(grasp or from_gizmo.grasp or from_keys.grasp))

    def _held_at(self, ee: np.ndarray, *, robot: bool) -> np.ndarray:
        """``h <- ee + clip(h - ee, HOLD_M)``: where the gripper is held (module docstring);
        ``h <- ee`` while the ``robot`` moves the gripper too (alpha > 0)."""
        hold = self._hold
        if hold is None or robot:
            hold = ee.copy()
        else:
            off = hold - ee
            dist = math.sqrt(float(off[0] * off[0] + off[1] * off[1] + off[2] * off[2]))
            if dist > HOLD_M:
                hold = ee + off * (HOLD_M / dist)
        self._hold = hold
        return hold

    def _relative(self, obs: TrialObservation) -> tuple[np.ndarray, np.ndarray, bool]:
        """``target = h + d`` after adding the keys' displacement, then ``d`` is spent; and the
        path, which moves by the user's displacements only."""
        dt = 1.0 / obs.rate_hz
        keys, grasp = self.keyboard.step(dt)
        ee = np.asarray(obs.ee, dtype=float)
        hold = self._held_at(ee, robot=obs.alpha > 0.0)
        with self._lock:
            pending = self._pending
            pending += keys
            target = hold + pending
            spent = pending * (1.0 - math.exp(-dt * GAIN_PER_S))
            pending -= spent
            hold += spent  # the hold moves on as the input is spent: the target stays put
            start = ee if self._path is None else self._path
            self._path = obs.reach.clamp(start + self._moved + keys)
            self._moved[:] = 0.0
            path = self._path.copy()
        return target, path, grasp

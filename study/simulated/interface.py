"""Simulated hands on the page's real inputs: the gizmo's handles and the held keys.

:class:`InterfaceUser` is the ``InputSource`` of one simulated trial. Each tick its
:class:`~study.simulated.user_model.SimulatedUser` (``goal_level``) says where the participant
wants the handle (``intent``) and whether they want the gripper closed; a hand turns that into
what a person does on the page, through the same :class:`app.teleop.ParticipantInput` the
browser drives (``set_target``, ``key_down``, ``key_up``, ``request_grasp``):

- :class:`GizmoHand` grabs one handle at a time -- the table plane, or one axis -- as seen from
  the page's camera: the horizontal part of the error first (the plane when it is diagonal,
  ``min(|ex|, |ey|) >= plane_share |e_xy|``, or when the larger axis points within 45 degrees
  of the line of sight and looks foreshortened; else that axis), then height. One drag moves
  the handle by the error projected on the handle, ``d``, along a minimum-jerk path lasting
  ``T = a + b log2(1 + |d| / W)`` (mouse dragging, MacKenzie et al. 1991), with hand noise; the
  part of ``d`` along the viewing direction is misjudged by a factor ``1 + e``,
  ``e ~ N(0, depth_error_sd)`` (depth is what a 2-D view hides). Between drags the hand lets go
  and re-grabs after a lognormal pause (look, move the pointer back to a handle).
- :class:`KeyHand` holds at most two axis keys (the horizontal ones first, then R/F), each while
  the error along its axis exceeds ``tolerance_m``; the handle moves at the page's key speed
  (``app.teleop.keyboard.KEY_SPEED_M_S``). The user sees the handle ``tau`` late and lets go
  early by ``key_anticipation`` of that delay, so a key overshoots by about
  ``speed tau (1 - anticipation)``; what is left is corrected with taps (``press``).

While the user re-plans after a surprise (``SimulatedUser.replanning``) the hand lets go of the
handle and of every key; while they wait for a knocked target to be stood up again it raises
the handle out of the way.
Under the relative mapping (``[control] input_mapping = "relative"``,
:class:`app.teleop.ParticipantInput`) a drag moves the gripper by the drag's displacement and
the handle returns to the gripper when let go: each grab starts from the gripper as it is then,
so a robot that pulls the gripper away between drags costs another drag; held keys give the
gripper a velocity, so a pull has to be held against.
"""

from __future__ import annotations

import math

import numpy as np

from app.teleop.participant_input import ParticipantInput
from app.teleop.types import TeleopCommand, TrialObservation
from study.simulated._vec import norm
from study.simulated.experience import RunExperience
from study.simulated.movement import HandNoise, fitts_time, minimum_jerk
from study.simulated.population import InterfaceParams, ParticipantParams
from study.simulated.trust import Trust
from study.simulated.user_model import SimulatedUser

AXIS_KEYS = (("s", "w"), ("d", "a"), ("f", "r"))
"""Per axis, the key that moves the handle toward minus and toward plus (``KEYMAP``)."""


def view_direction(p: InterfaceParams) -> np.ndarray:
    """Unit vector from the page's camera toward the task (``study.server.page_scene.frame_task`` puts
    the camera at ``look_at + r (cos el cos az, cos el sin az, sin el)``)."""
    az, el = math.radians(p.view_azimuth_deg), math.radians(p.view_elevation_deg)
    return -np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


FORESHORTENED_COS = math.cos(math.radians(45.0))
"""An axis arrow within 45 degrees of the line of sight looks short and is hard to drag along:
a person moves that way with the table-plane handle instead."""


def choose_handle(
    error: np.ndarray, *, plane_share: float, tolerance: float, view: np.ndarray | None = None
) -> tuple[int, ...]:
    """The axes of the handle a person grabs for ``error`` (3,): over the table first (until
    within twice ``tolerance``: lined up above the object), then height. Over the table: the
    plane when the error is diagonal, else the larger axis -- unless that axis points along
    the viewing direction ``view`` (foreshortened on the screen), then the plane too."""
    ex, ey, ez = (abs(float(v)) for v in error)
    horizontal = math.hypot(ex, ey)
    if horizontal > 2.0 * tolerance or (horizontal > tolerance and horizontal >= ez):
        axis = 0 if ex >= ey else 1
        if min(ex, ey) >= plane_share * horizontal:
            return (0, 1)
        if view is not None and abs(float(view[axis])) > FORESHORTENED_COS:
            return (0, 1)
        return (axis,)
    if ez > tolerance:
        return (2,)
    return (0,) if ex >= ey else (1,)


class GizmoHand:
    """One handle at a time, dragged with the mouse (see the module docstring)."""

    def __init__(
        self, params: InterfaceParams, *, rng: np.random.Generator, noise: HandNoise
    ) -> None:
        self.p = params
        self.rng = rng
        self.noise = noise
        self.view = view_direction(params)
        self.handle: tuple[int, ...] | None = None  # the axes being dragged, None: let go
        self.dragged = np.zeros(3)  # where the hand last put the handle
        self.drags = 0
        self._from = np.zeros(3)
        self._move = np.zeros(3)
        self._mask = np.zeros(3)
        self._t0 = 0.0
        self._length = 1.0
        self._next_grab = 0.0

    def act(
        self,
        t: float,
        dt: float,
        *,
        handle_at: np.ndarray,
        intent: np.ndarray,
        inp: ParticipantInput,
    ) -> None:
        """One tick: when let go and rested, grab a handle toward ``intent`` (unless within
        ``tolerance`` of the shown ``handle_at``); while dragging, ``set_target`` the next point
        of the drag, ``from + d s(phi) + noise``, ``phi = (t - t0) / T``."""
        if self.handle is None:
            if t < self._next_grab:
                return
            error = intent - handle_at
            if norm(error) < self.p.tolerance_m:
                return
            self._grab(t, handle_at, error)
        assert self.handle is not None
        phi = min((t - self._t0) / self._length, 1.0)
        shake = self.noise.step(dt) * self._mask  # the handle moves only along its axes
        self.dragged = self._from + self._move * minimum_jerk(phi) + shake
        inp.set_target(self.dragged)
        if phi >= 1.0:  # let go; look, then grab again
            self.let_go(t, inp)

    def let_go(self, t: float, inp: ParticipantInput) -> None:
        """Release the handle (if held); the next grab comes after a look (a regrab pause)."""
        if self.handle is None:
            return
        self.handle = None
        inp.let_go()
        self._next_grab = t + self.p.regrab_s * math.exp(
            self.p.regrab_sigma * float(self.rng.standard_normal())
        )

    def _grab(self, t: float, handle_at: np.ndarray, error: np.ndarray) -> None:
        axes = choose_handle(
            error, plane_share=self.p.plane_share, tolerance=self.p.tolerance_m, view=self.view
        )
        mask = np.zeros(3)
        mask[list(axes)] = 1.0
        move = error * mask
        depth = self.view * mask  # the viewing direction within the handle's axes
        size = norm(depth)
        if size > 1e-6:
            depth /= size
            along = float(move @ depth)
            move = move + depth * along * self.p.depth_error_sd * float(self.rng.standard_normal())
        self.handle = axes
        self._mask = mask
        self.drags += 1
        self._from = handle_at.copy()
        self._move = move
        self._t0 = t
        self._length = fitts_time(
            norm(move), a=self.p.drag_a_s, b=self.p.drag_b_s_per_bit, width=0.02
        )


class KeyHand:
    """One or two held axis keys, then taps (see the module docstring)."""

    def __init__(self, params: InterfaceParams, *, delay_s: float) -> None:
        self.p = params
        self.delay_s = delay_s
        self.held: dict[int, str] = {}  # axis -> key held
        self.presses = 0
        self._tap_ready = 0.0
        self._axis_ready = [0.0, 0.0, 0.0]  # after letting go, look before pressing again

    def act(
        self, t: float, *, seen_handle: np.ndarray, intent: np.ndarray, inp: ParticipantInput
    ) -> None:
        """One tick: let go of keys whose axis is within ``tolerance`` (or overshot), hold keys
        for axes off by twice that (over the table first, at most two), else tap once per look."""
        # where the handle is now, as the user reckons it: seen tau ago, plus the held keys'
        # travel since, of which they anticipate a share
        lead = inp.keyboard.speed * self.delay_s * self.p.key_anticipation
        now = seen_handle.copy()
        for axis, key in self.held.items():
            now[axis] += lead if key == AXIS_KEYS[axis][1] else -lead
        error = intent - now
        tol = self.p.tolerance_m
        for axis in [a for a in self.held if abs(error[a]) < tol or self._wrong_way(a, error)]:
            inp.key_up(self.held.pop(axis))
            self._axis_ready[axis] = t + self.delay_s
            self._tap_ready = max(self._tap_ready, t + self.delay_s)
        horizontal = math.hypot(error[0], error[1]) > 2.0 * tol
        wanted = [a for a in ((0, 1) if horizontal else (2, 0, 1)) if abs(error[a]) >= 2.0 * tol]
        for axis in wanted:
            if axis not in self.held and len(self.held) < 2 and t >= self._axis_ready[axis]:
                key = AXIS_KEYS[axis][1 if error[axis] > 0 else 0]
                inp.key_down(key)
                self.held[axis] = key
                self.presses += 1
        if not self.held and t >= self._tap_ready:  # fine adjustment: one tap per look
            axis = int(np.argmax(np.abs(error)))
            if abs(error[axis]) >= tol:
                inp.key_down(AXIS_KEYS[axis][1 if error[axis] > 0 else 0])
                inp.key_up(AXIS_KEYS[axis][1 if error[axis] > 0 else 0])
                self.presses += 1
                self._tap_ready = t + self.delay_s + 0.1

    def let_go(self, t: float, inp: ParticipantInput) -> None:
        """Release every held key (the user stops); look before pressing again."""
        for axis, key in self.held.items():
            inp.key_up(key)
            self._axis_ready[axis] = t + self.delay_s
        self.held.clear()
        self._tap_ready = max(self._tap_ready, t + self.delay_s)

    def _wrong_way(self, axis: int, error: np.ndarray) -> bool:
        plus = self.held[axis] == AXIS_KEYS[axis][1]
        return (error[axis] > 0) != plus


class InterfaceUser:
    """A simulated participant's trial through the page's gizmo or keys (``InputSource``).

    ``trust``: the participant's trust in the robot, carried over from their earlier runs
    (:class:`~study.simulated.trust.Trust`; a fresh one if ``None``); ``mapping``: the page's
    input mapping (``absolute`` or ``relative``)."""

    def __init__(
        self,
        params: ParticipantParams,
        *,
        rng: np.random.Generator,
        trust: Trust | None = None,
        mapping: str = "absolute",
    ) -> None:
        self.params = params
        self.rng = rng
        self.user = SimulatedUser(params, rng=rng, goal_level=True, trust=trust)
        self.input = ParticipantInput(mapping=mapping)
        self._handle: np.ndarray | None = None  # where the page draws the handle (relative)
        self.keyboard = params.interface.keyboard >= 0.5
        self.hand: GizmoHand | KeyHand
        if self.keyboard:
            self.hand = KeyHand(params.interface, delay_s=params.motor.reaction_delay_s)
        else:
            noise = HandNoise(sd=params.motor.noise_sd_m, tau=params.motor.noise_tau_s, rng=rng)
            self.hand = GizmoHand(params.interface, rng=rng, noise=noise)
        self._grasp = False
        self._t_prev: float | None = None

    @property
    def interface(self) -> str:
        return "keyboard" if self.keyboard else "gizmo"

    def command(self, obs: TrialObservation) -> TeleopCommand:
        """Perceive and decide (the goal-level user), act on the page's input, then return
        what that input gives the trial this tick (``ParticipantInput.command``)."""
        self.user.command(obs)  # perceive, decide: the intent and the grasp wish
        dt = 1.0 / obs.rate_hz if self._t_prev is None else max(obs.t - self._t_prev, 1e-6)
        self._t_prev = obs.t
        grasp = self.user.grasp_closed
        if grasp and not self._grasp:
            self.input.request_grasp()
        self._grasp = grasp
        drawn = self.input.handle_position(obs.ee) if self.input.relative else None
        if drawn is not None:
            self._handle = drawn
        if self.user.phase == "reach" and not self.user.replanning:  # the handle matters then
            intent = self.user.intent
            if isinstance(self.hand, KeyHand):
                seen = self.user.seen_handle if self.user.seen_handle is not None else intent
                self.hand.act(obs.t, seen_handle=seen, intent=intent, inp=self.input)
            else:
                handle = self._handle if self._handle is not None else obs.user_target
                handle = np.asarray(handle, dtype=float)
                self.hand.act(obs.t, dt, handle_at=handle, intent=intent, inp=self.input)
                if self.input.relative and self.hand.handle is not None:
                    self._handle = self.hand.dragged
        else:
            self.hand.let_go(obs.t, self.input)
        return self.input.command(obs)

    def experience(self, *, duration_s: float | None = None, success: bool) -> RunExperience:
        """What this run was like (the questionnaire's input): see ``SimulatedUser``."""
        return self.user.experience(duration_s=duration_s, success=success)

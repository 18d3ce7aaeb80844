"""The study's task: grasp the target object and lift it ``lift_height_m`` above its rest height.

Phases: ``reach`` (the user steers) -> a grasp request closes the gripper in physics
(``closing``; the objects within ``WAKE_M`` of the gripper wake under ``contacts = "grasp"``) ->
after ``CLOSE_S`` either an object is held (``grasped``; the arm lifts it by itself at
``LIFT_SPEED``, ``lifting``) or not (``grasp_missed``; the gripper stays closed on nothing for
``MISSED_HOLD_S``, ``missed``, so that a person watching sees it closed, then opens again for
``REOPEN_S``, ``reopening``, then ``reach``). Lifting ends the run once the object is ``lift_height_m`` up
(``lifted``: ``success`` if it is the target, else ``wrong_object``); contact lost for ``DROP_S``
(``dropped``) or no height within ``LIFT_TIMEOUT_S`` (``lift_failed``) ends it as ``dropped``
under ``on_knock = "end"``, and under ``"reset"`` opens the gripper for another reach.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from app.trial.events import EventKind, TrialEvent

if TYPE_CHECKING:
    from app.robot.simulation import Simulation
    from app.teleop.ik_step import IKStep
    from app.trial.config import TrialConfig
    from app.trial.tasks.task import TrialParts

__all__ = [
    "CLOSE_S",
    "DROP_S",
    "LIFT_SPEED",
    "LIFT_TIMEOUT_S",
    "MISSED_HOLD_S",
    "REOPEN_S",
    "WAKE_M",
    "LiftTask",
]

CLOSE_S = 0.4  # gripper closing time before judging the grasp
MISSED_HOLD_S = 0.6
"""After a missed grasp the gripper stays closed this long (s) before it opens: the fingers close
fully in 0.27 s and took as long to open again, so a page drawing 5-10 frames a second showed a
closed gripper in a frame or two, which a participant did not notice."""
REOPEN_S = 0.4  # after a missed grasp, time the gripper takes to open again
LIFT_TIMEOUT_S = 3.0  # the automatic lift must reach the height within this time
LIFT_SPEED = 0.1  # m/s, automatic lift
DROP_S = 0.15  # contact lost this long while lifting = dropped
WAKE_M = 0.15  # a grasp wakes the objects within this horizontal distance of the gripper

_CLOSED = ("closing", "missed", "lifting")


class LiftTask:
    """Grasp and lift (module docstring); ``phase`` is one of ``reach``, ``closing``,
    ``lifting``, ``missed``, ``reopening`` and ``done``."""

    def __init__(self) -> None:
        self.phase = "reach"
        self.reaching = True
        self.gripper_closed = False
        self.held: int | None = None
        self._phase_t = 0.0
        self._hold_q = np.zeros(0)
        self._lift_target = np.zeros(3)
        self._lost_t: float | None = None

    def start(self, trial: TrialParts) -> None:
        self.sim: Simulation = trial.sim
        self.ik: IKStep = trial.ik
        self.config: TrialConfig = trial.config
        self.names = trial.scene.object_names
        self.target_index = trial.scene.target_index
        self._hold_q = trial.scene.start_q.copy()

    def stop(self) -> None:
        self._set("done")

    def _set(self, phase: str) -> None:
        self.phase = phase
        self.reaching = phase == "reach"
        self.gripper_closed = phase in _CLOSED

    def _enter(
        self, phase: str, t: float, events: list[TrialEvent], event: TrialEvent | None = None
    ) -> None:
        self._set(phase)
        self._phase_t = t
        if event is not None:
            events.append(event)

    # ---- each tick, before physics ----------------------------------------------------------
    def control(
        self, q: np.ndarray, t: float, *, request: bool, events: list[TrialEvent]
    ) -> np.ndarray | None:
        """``None`` while reaching (the user steers); a grasp request holds the arm still; the
        lift raises it; after a miss it holds still, the gripper closed and then opening, until
        the gripper is open; then reaching resumes."""
        phase = self.phase
        if phase == "reach":
            if not request:
                return None
            self._enter("closing", t, events, TrialEvent(EventKind.GRASP_REQUESTED))
            if self.sim.contacts == "grasp":  # wake what the fingers can reach
                near = self.sim.objects_near(self.sim.ee, WAKE_M)
                self.sim.set_grip_contacts(True, only=near)
            self._hold_q = q
            return q
        if phase == "lifting":
            return self.ik(q, self._lift_target, max_speed=LIFT_SPEED)
        if phase == "missed" and t - self._phase_t >= MISSED_HOLD_S:
            self._enter("reopening", t, events)
        elif phase == "reopening" and t - self._phase_t >= REOPEN_S:
            if self.sim.objects_at_rest():  # untouched: "grasp" rests them again
                if self.sim.contacts == "grasp":
                    self.sim.set_grip_contacts(False)
            else:  # disturbed objects stay physical (they may be moving or tipped)
                events.append(TrialEvent(EventKind.OBJECTS_DISTURBED))
            self._enter("reach", t, events)
        return self._hold_q

    # ---- each tick, after physics -----------------------------------------------------------
    def judge(self, t: float, events: list[TrialEvent]) -> str | None:
        """Closing: after ``CLOSE_S`` grasped or missed. Lifting: lifted, dropped or failed."""
        if self.phase == "closing" and t - self._phase_t >= CLOSE_S:
            self._grasp_judged(t, events)
        elif self.phase == "lifting" and self.held is not None:
            return self._lift_judged(t, events, self.held)
        return None

    def _grasp_judged(self, t: float, events: list[TrialEvent]) -> None:
        held = self.sim.held_object()
        if held is None:
            self._enter("missed", t, events, TrialEvent(EventKind.GRASP_MISSED))
            return
        self.held = held
        self._lost_t = None
        self._lift_target = self.sim.ee + np.array([0.0, 0.0, self.config.lift_height_m + 0.03])
        self._enter("lifting", t, events, TrialEvent(EventKind.GRASPED, obj=self.names[held]))

    def _lift_judged(self, t: float, events: list[TrialEvent], i: int) -> str | None:
        if self.sim.held_object() == i:
            self._lost_t = None
        elif self._lost_t is None:
            self._lost_t = t
        height = float(self.sim.object_heights()[i])
        if height >= self.config.lift_height_m and self._lost_t is None:
            events.append(TrialEvent(EventKind.LIFTED, obj=self.names[i]))
            return "success" if i == self.target_index else "wrong_object"
        if self._lost_t is not None and t - self._lost_t >= DROP_S:
            return self._lost(t, TrialEvent(EventKind.DROPPED, obj=self.names[i]), events)
        if t - self._phase_t >= LIFT_TIMEOUT_S:
            return self._lost(t, TrialEvent(EventKind.LIFT_FAILED, obj=self.names[i]), events)
        return None

    def _lost(self, t: float, event: TrialEvent, events: list[TrialEvent]) -> str | None:
        """The held object fell out of the gripper (or would not come up): the run ends as
        ``dropped`` under ``on_knock = "end"``; under ``"reset"`` the gripper opens where the
        arm is (it went back to where the grasp began at up to 1 m/s, a tester saw it jerk),
        and the user may reach again (the trial puts the object back: ``Accidents.slipped``)."""
        events.append(event)
        if self.config.on_knock == "end":
            return "dropped"
        self.held = None
        self._lost_t = None
        self._hold_q = self.sim.q  # the arm stays where it lost the object while it opens
        self._enter("reopening", t, events)
        return None

"""Trial tasks: a task defined here alone (carry the object into a region) runs a headless trial."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from app.teleop import ScriptedInput, TeleopCommand, TrialObservation
from app.trial import Trial, run_trial
from app.trial.events import EventKind, TrialEvent
from app.trial.tasks import LiftTask, Task
from study.protocol import trial_config_from_protocol

CLOSE_S = 0.4
REGION = (np.array([0.47, 0.17, 0.07]), np.array([0.53, 0.23, 0.13]))
"""Where the box (resting at 0.64, 0.06, 0.035 in the easy scene) is to be carried."""


class PlaceTask:
    """Grasp an object and carry it into an axis-aligned box ``lo..hi``: ``success`` once the
    held target is inside (``wrong_object`` for the other one, ``dropped`` if it falls)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray) -> None:
        self.lo, self.hi = lo, hi
        self.reaching = True  # the user steers throughout, also while carrying
        self.gripper_closed = False
        self.held: int | None = None
        self._closed_t = math.inf
        self._hold = np.zeros(0)

    def start(self, trial: Trial) -> None:
        self.sim = trial.sim
        self.names = trial.scene.object_names
        self.target = trial.scene.target_index

    def control(
        self, q: np.ndarray, t: float, *, request: bool, events: list[TrialEvent]
    ) -> np.ndarray | None:
        if request and not self.gripper_closed:
            self.gripper_closed, self._closed_t, self._hold = True, t, q
            events.append(TrialEvent(EventKind.GRASP_REQUESTED))
        if self.gripper_closed and self.held is None:
            return self._hold  # still while the fingers close
        return None

    def judge(self, t: float, events: list[TrialEvent]) -> str | None:
        if self.held is None:
            if t - self._closed_t >= CLOSE_S:
                self.held = self.sim.held_object()
                if self.held is None:  # missed: open and let the user reach again
                    self.gripper_closed, self._closed_t = False, math.inf
                    events.append(TrialEvent(EventKind.GRASP_MISSED))
                else:
                    events.append(TrialEvent(EventKind.GRASPED, obj=self.names[self.held]))
            return None
        if self.sim.held_object() != self.held:
            events.append(TrialEvent(EventKind.DROPPED, obj=self.names[self.held]))
            return "dropped"
        position = self.sim.object_positions()[self.held]
        if np.all(position >= self.lo) and np.all(position <= self.hi):
            return "success" if self.held == self.target else "wrong_object"
        return None

    def stop(self) -> None:
        self.reaching = self.gripper_closed = False


class Carrier:
    """Reaches and grasps like ``ScriptedInput``; holding the object, moves the target at
    ``speed`` so the object's centre heads for ``goal``."""

    def __init__(self, goal: np.ndarray, *, speed: float = 0.1) -> None:
        self.reach = ScriptedInput(seed=0, noise=0.0)
        self.goal = goal
        self.speed = speed
        self._target: np.ndarray | None = None

    def command(self, obs: TrialObservation) -> TeleopCommand:
        if obs.grasped is None:
            return self.reach.command(obs)
        if self._target is None:
            self._target = obs.user_target.copy()
        obj = obs.object_positions[obs.target_index]
        step = obs.ee + (self.goal - obj) - self._target
        size = float(np.linalg.norm(step))
        reach = self.speed / obs.rate_hz
        self._target = self._target + (step if size <= reach else step * (reach / size))
        return TeleopCommand(self._target.copy(), False)


def test_a_task_defined_here_runs_a_headless_trial_to_success(protocol_path) -> None:
    task: Task = PlaceTask(*REGION)
    config = trial_config_from_protocol(protocol_path, "easy-right", "none")
    config = dataclasses.replace(config, time_limit_s=30)
    result = run_trial(config, Carrier((REGION[0] + REGION[1]) / 2), task=task)
    assert result.outcome == "success", [e for _, e in result.events]
    kinds = [e.kind for _, e in result.events]
    assert EventKind.GRASPED in kinds and EventKind.LIFTED not in kinds  # placed, not lifted
    last = result.records[-1]
    assert last.gripper < 0.04  # carried in the closed gripper to the end


def test_the_default_task_is_grasp_and_lift(protocol_path) -> None:
    config = trial_config_from_protocol(protocol_path, "easy-right", "none")
    trial = Trial(config, ScriptedInput(seed=0))
    assert isinstance(trial.task, LiftTask) and trial.task.reaching

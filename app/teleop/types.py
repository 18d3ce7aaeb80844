"""What an input source sees each tick and what it answers.

An ``InputSource`` (browser gizmo, keyboard, scripted or simulated user) is asked once per control
tick: ``command(obs) -> TeleopCommand``. The command is an absolute end-effector *target*
(world frame, metres) plus whether the gripper should be closed; the trial clamps the target to
the interface's reach and turns it into ``U`` by a velocity-limited IK step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from app.frozen import quick_init
from app.teleop.reach import ReachRegion


@quick_init
@dataclass(frozen=True)
class TeleopCommand:
    """The user's wish this tick: end-effector ``target`` (3,) and ``grasp`` (True = close).

    ``path`` (3,), when given: where the user's own input has taken the gripper, if that is not
    the target -- under a relative mapping the target is the gripper plus what is still to
    come, so it moves with whatever moves the gripper, the robot included. The robot predicts
    the user's goal from their input's positions (``path`` if given, else ``target``).
    """

    target: np.ndarray
    grasp: bool = False
    path: np.ndarray | None = None


@quick_init
@dataclass(frozen=True)
class TrialObservation:
    """The state an input source may look at (server side only; never sent to a browser as is).

    ``q``: arm configuration (7,); ``ee``: end-effector (tool centre point) position (3,);
    ``user_target``: last clamped target (3,); ``goal_positions``: (n, 3) the robot's goals (grasp
    points) in the order of ``goal_names``; they follow an object once it was moved; ``target_index``: which goal the participant was asked to pick up;
    ``alpha``/``predicted``: the last arbitration value and predicted goal index;
    ``object_positions``: the objects' centres now (n, 3), same order; ``grasp_points``: the
    grasp points now (n, 3), moved with their objects at once (a nudged object is re-aimed at
    there; defaults to ``goal_positions``); ``knocks``: how many times an object has been
    knocked over or pushed off the table so far in the trial (what a person sees fall);
    ``lying``: the indices of the objects lying now (knocked over or off the table, not yet
    stood up again); ``held_above``: the object the open gripper is held above because it would
    come down on it rather than around it (``app.teleop.guarded_descent``; the page says so and
    what to do). The arrays are shared: read, never write.
    """

    t: float
    q: np.ndarray
    ee: np.ndarray
    gripper_closed: bool
    user_target: np.ndarray
    reach: ReachRegion
    goal_names: tuple[str, ...]
    goal_positions: np.ndarray
    target_index: int
    alpha: float = 0.0
    predicted: int = -1
    grasped: str | None = None
    rate_hz: float = 100.0
    object_positions: np.ndarray | None = None
    grasp_points: np.ndarray | None = None
    knocks: int = 0
    lying: tuple[int, ...] = ()
    held_above: int | None = None

    def __post_init__(self) -> None:
        if self.grasp_points is None:
            object.__setattr__(self, "grasp_points", self.goal_positions)


@runtime_checkable
class InputSource(Protocol):
    """Anything that turns an observation into a ``TeleopCommand`` once per control tick.

    Implementations must be cheap (called at the control rate) and, when fed from another
    thread (a UI callback), lock their own state.
    """

    def command(self, obs: TrialObservation) -> TeleopCommand: ...

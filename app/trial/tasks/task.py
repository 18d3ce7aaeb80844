"""What a trial asks of its task: the small interface between the control loop and the goal.

The trial (``app.trial.trial.Trial``) runs input -> IK -> blending -> physics every tick; the task
says what the tick means. While ``reaching`` the user, blended with the robot, steers the arm;
otherwise the task drives it (``control`` returns the command: hold still while the gripper
closes, lift a grasped object, ...). After each physics step ``judge`` says whether the task
ended the run and how (an outcome of ``app.trial.records.OUTCOMES``). ``gripper_closed`` is
what the physics and the input sources see of the gripper; ``held`` is the object the gripper
holds (its index among the scene's objects), ``None`` if none.

A task object serves one trial: ``start(trial)`` binds it to the trial's physics, scene and
configuration before the first tick, ``stop()`` ends it with the run. The grasp-and-lift task of
the study is :class:`app.trial.tasks.lift.LiftTask`; a new task is one class with these members,
given to ``Trial(..., task=...)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import numpy as np

    from app.robot.scene import Scene
    from app.robot.simulation import Simulation
    from app.teleop.ik_step import IKStep
    from app.trial.config import TrialConfig
    from app.trial.events import TrialEvent

__all__ = ["Task", "TrialParts"]


class TrialParts(Protocol):
    """What a task sees of its trial (``app.trial.trial.Trial`` has these): the physics, the
    scene, the configuration and the IK step that turns a target into joint positions."""

    @property
    def sim(self) -> Simulation: ...

    @property
    def scene(self) -> Scene: ...

    @property
    def config(self) -> TrialConfig: ...

    @property
    def ik(self) -> IKStep: ...


class Task(Protocol):
    """A trial's task (module docstring). ``reaching``, ``gripper_closed`` and ``held`` are read
    every tick: plain attributes, kept current by ``control``, ``judge`` and ``stop``."""

    reaching: bool
    gripper_closed: bool
    held: int | None

    def start(self, trial: TrialParts) -> None:
        """Bind to ``trial`` (its ``sim``, ``scene``, ``config``, ``ik``) before the first tick."""

    def control(
        self, q: np.ndarray, t: float, *, request: bool, events: list[TrialEvent]
    ) -> np.ndarray | None:
        """The arm's command this tick, or ``None`` while the user steers (``reaching``);
        ``request``: the user asked for a grasp this tick; ``q``: the configuration now."""

    def judge(self, t: float, events: list[TrialEvent]) -> str | None:
        """After the physics step at time ``t``: the outcome if the task ends the run, else
        ``None``; what happened goes to ``events``."""

    def stop(self) -> None:
        """The run ended (an outcome, an abort): the task is done."""

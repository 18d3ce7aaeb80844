"""Trial tasks: what a trial's ticks mean (``Task``) and the study's grasp-and-lift
(``LiftTask``); one task per module."""

from app.trial.tasks.lift import LiftTask
from app.trial.tasks.task import Task

__all__ = ["LiftTask", "Task"]

"""Teleoperation: input sources become the user's target, and the target becomes ``U``.

``ReachRegion`` clamps targets to what the interface can point at; ``ik_step`` turns a target
into the next configuration ``U`` with a velocity limit; input sources (``GizmoInput``,
``KeyboardInput``, ``ScriptedInput``) implement ``InputSource.command(obs) -> TeleopCommand``.
"""

from app.teleop.errors import InvalidTargetError, TeleopError
from app.teleop.reach import ReachRegion
from app.teleop.types import InputSource, TeleopCommand, TrialObservation

__all__ = [
    "InputSource",
    "InvalidTargetError",
    "ReachRegion",
    "TeleopCommand",
    "TeleopError",
    "TrialObservation",
]

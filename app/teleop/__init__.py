"""Teleoperation: input sources become the user's target, and the target becomes ``U``.

``ReachRegion`` clamps targets to what the interface can point at; ``IKStep`` turns a target
into the next configuration ``U`` with a velocity limit; input sources (``GizmoInput``,
``KeyboardInput``, ``ScriptedInput``, ``IdleInput``, and ``ParticipantInput``: the page's
gizmo and keys as one device, shared by the browser and the simulated users) implement
``InputSource.command(obs) -> TeleopCommand``.
"""

from app.teleop.errors import InvalidTargetError, TeleopError
from app.teleop.gizmo import GizmoInput
from app.teleop.ik_step import IKStep
from app.teleop.keyboard import KeyboardInput
from app.teleop.participant_input import InputFrozen, ParticipantInput
from app.teleop.reach import ReachRegion
from app.teleop.scripted import IdleInput, ScriptedInput
from app.teleop.types import InputSource, TeleopCommand, TrialObservation

__all__ = [
    "GizmoInput",
    "IKStep",
    "IdleInput",
    "InputFrozen",
    "InputSource",
    "InvalidTargetError",
    "KeyboardInput",
    "ParticipantInput",
    "ReachRegion",
    "ScriptedInput",
    "TeleopCommand",
    "TeleopError",
    "TrialObservation",
]

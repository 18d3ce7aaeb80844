"""The participant's composite input, re-exported: it lives in ``app.teleop.participant_input``
(an input device beside the gizmo and the keys; the page and the simulated users share it)."""

from app.teleop.participant_input import InputFrozen, ParticipantInput

__all__ = ["InputFrozen", "ParticipantInput"]

"""A simulated participant's lived runs and the screens it answers, for the simulated-participant
and questionnaire tests."""

from __future__ import annotations

from types import SimpleNamespace

from study.protocol import LikertItem, Scale
from study.session import Progress, Screen, TrialSummary
from study.simulated import SimulatedUser
from study.simulated.interface import InterfaceUser
from study.simulated.participant import SimulatedParticipant

ANCHORS = tuple(str(k) for k in range(1, 8))
CONFIG = SimpleNamespace(extra={"input_mapping": "absolute"})  # what the factory reads of it


def screen(questionnaire: str, *items: str) -> Screen:
    return Screen(
        phase="questions",
        title="Questions",
        text="",
        progress=Progress(1, 8),
        items=tuple(LikertItem(i, i, Scale("agree7", ANCHORS)) for i in items),
        actions=("answer",),
        questionnaire=questionnaire,
    )


def lived(person: SimulatedParticipant, *, duration: float, success: bool = True) -> None:
    user = person(config=CONFIG, seed=1)  # type: ignore[arg-type]
    assert isinstance(user, InterfaceUser) and isinstance(user.user, SimulatedUser)
    summary = TrialSummary(1, "success" if success else "timeout", success, duration, 100)
    person.observe(summary, time_limit_s=120.0)

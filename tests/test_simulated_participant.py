"""``SimulatedParticipant``: the input factory and answerer the session loop drives (no MuJoCo)."""

from __future__ import annotations

from pathlib import Path

import pytest

from study.simulated import SimulationRunError, load_population
from study.simulated.participant import SimulatedParticipant
from study.simulated.runner import participant_id, plan_jobs, session_seed
from tests.support.simulated_people import CONFIG, lived, screen


def participant() -> SimulatedParticipant:
    return SimulatedParticipant(load_population().draw(0, seed=2))


def test_practice_runs_become_the_reference_and_are_rated() -> None:
    person = participant()
    for d in (8.0, 7.0, 6.0):
        lived(person, duration=d)
    answers = person.answer(screen("after_training", "helpful", "matched", "teammate"))
    assert set(answers) == {"helpful", "matched", "teammate"}
    assert all(1 <= v <= 7 for v in answers.values())
    assert [r.duration_s for r in person.training_runs] == [8.0, 7.0, 6.0]
    assert person.questionnaire.reference_s == pytest.approx((8 * 7 * 6) ** (1 / 3))


def test_preference_leans_to_the_much_faster_run() -> None:
    prefs = []
    for index in range(12):
        person = SimulatedParticipant(load_population().draw(index, seed=2))
        for d in (8.0, 7.0, 6.0):
            lived(person, duration=d)
        person.answer(screen("after_training", "helpful"))
        lived(person, duration=40.0, success=False)
        person.answer(screen("after_run", "helpful"))
        lived(person, duration=5.0)
        person.answer(screen("after_run", "helpful"))
        prefs.append(person.answer(screen("after_task", "preference"))["preference"])
    assert sum(p > 4 for p in prefs) >= 10  # 7 = the second run


def test_aborted_runs_are_not_remembered() -> None:
    person = participant()
    person(config=CONFIG, seed=1)  # type: ignore[arg-type]
    person.observe(None, time_limit_s=120.0)
    assert person.runs == []
    with pytest.raises(SimulationRunError, match="before any run"):
        person.answer(screen("after_run", "helpful"))


def test_input_is_seeded_by_participant_and_attempt() -> None:
    person = participant()
    a = person(config=CONFIG, seed=5)  # type: ignore[arg-type]
    b = person(config=CONFIG, seed=5)  # type: ignore[arg-type]
    c = person(config=CONFIG, seed=6)  # type: ignore[arg-type]
    assert a.rng.random() == b.rng.random() != c.rng.random()


def test_planned_participants_get_ids_rows_and_seeds(tmp_path: Path, protocol_path: Path) -> None:
    from study.protocol import load_protocol
    from study.session import open_store

    protocol = load_protocol(protocol_path)
    with open_store(tmp_path / "s.db", protocol) as store:
        jobs = plan_jobs(store, n=4, seed=7, first=2)
    assert [j.participant for j in jobs] == ["sim7-003", "sim7-004", "sim7-005", "sim7-006"]
    assert [j.schedule_row for j in jobs] == [0, 1, 2, 3]
    assert jobs[0].session_seed == session_seed(2, seed=7) != session_seed(3, seed=7)
    assert participant_id(0, seed=-1) == "sim-1-001"

"""The simulator logs a participant's drawn parameters through ``Session.record_event`` (the
lease-checked path), before driving the session."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import pytest

from study.protocol import load_protocol
from study.session import Session, open_store
from study.simulated import DEFAULT_POPULATION_PATH
from study.simulated import job as job_module
from study.simulated.job import run_participant
from study.simulated.runner import plan_jobs


def test_simulated_parameters_are_recorded_through_the_session(
    tmp_path: Path, protocol_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    recorded: list[tuple[str, dict[str, Any]]] = []
    record_event = Session.record_event

    def spy(self: Session, kind: str, detail: Any = None) -> None:
        recorded.append((kind, dict(detail or {})))
        record_event(self, kind, detail)

    monkeypatch.setattr(Session, "record_event", spy)
    # the event is written before the session is driven; the session itself is not needed here
    monkeypatch.setattr(job_module, "run_headless", lambda session, **_: None)
    protocol = load_protocol(protocol_path)
    store = open_store(tmp_path / "sim.db", protocol)
    try:
        (job,) = plan_jobs(store, n=1, seed=5)
        result = run_participant(
            job, store=store, protocol=protocol, population_path=DEFAULT_POPULATION_PATH, seed=5
        )
        assert result.error is None
        assert [kind for kind, _ in recorded] == ["simulated_participant"]
        (event,) = [e for e in store.events() if e.kind == "simulated_participant"]
        assert event.detail == recorded[0][1]
        # provenance without the researcher's directories: the file's name and content hash
        assert event.detail["population"] == DEFAULT_POPULATION_PATH.name
        digest = hashlib.sha256(DEFAULT_POPULATION_PATH.read_bytes()).hexdigest()
        assert event.detail["population_sha256"] == digest
        assert str(DEFAULT_POPULATION_PATH.parent) not in json.dumps(event.detail)
        assert event.detail["params"]
    finally:
        store.close()

"""One simulated participant: who to simulate (:class:`ParticipantJob`), their whole session
driven to the end through the real session engine (:func:`run_participant`) and how it went
(:class:`ParticipantResult`). Used by the local engine (:mod:`study.simulated.local_engine`)
and by the Dask engine's tasks (:mod:`study.simulated.dask_engine`) alike.
"""

from __future__ import annotations

import hashlib
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from study.session import Session
from study.session.headless import run_headless
from study.simulated.population import load_population
from study.store import StoreWriteError

if TYPE_CHECKING:
    from study.protocol import Protocol
    from study.store import Store

SAMPLE_FLUSH_S = 0.25
"""Samples are committed in batches this often (wall time; the SampleWriter's maximum): a
simulated trial runs many times faster than real time, so fewer, larger write transactions
keep concurrent workers from queueing on the store's write lock."""


@dataclass(frozen=True)
class ParticipantJob:
    """Who to simulate: population index, pseudonymous ID, design row and session seed."""

    index: int
    participant: str
    schedule_row: int
    session_seed: int


@dataclass(frozen=True)
class ParticipantResult:
    """How one simulated session went (from the store)."""

    index: int
    participant: str
    status: str
    trials_completed: int
    trial_rows: int
    ratings: int
    outcomes: dict[str, int]
    sim_s: float
    wall_s: float
    error: str | None = None


def run_participant(
    job: ParticipantJob,
    *,
    store: Store,
    protocol: Protocol,
    population_path: Path,
    seed: int,
    on_trial: Callable[[], None] | None = None,
) -> ParticipantResult:
    """Enrol ``job``'s participant and drive their whole session to the end."""

    start = time.perf_counter()
    population = load_population(population_path)
    params = population.draw(job.index, seed=seed)
    person = population.model.participant(params)
    session = Session.enrol(
        store,
        protocol,
        job.participant,
        seed=job.session_seed,
        schedule_row=job.schedule_row,
        demographics={"simulated": True, "population_index": job.index, "population_seed": seed},
        flush_interval_s=SAMPLE_FLUSH_S,
    )
    error: str | None = None
    fault: StoreWriteError | None = None
    try:
        session.record_event(
            "simulated_participant",
            {
                # the file's name and content hash, not the researcher's absolute path
                "population": Path(population_path).name,
                "population_sha256": hashlib.sha256(Path(population_path).read_bytes()).hexdigest(),
                "params": asdict(params),
            },
        )
        run_headless(
            session,
            answerer=person,
            input_factory=person,
            on_trial=(lambda _summary: on_trial()) if on_trial else None,
        )
    except StoreWriteError as exc:  # the disk, not this participant: the whole run stops
        fault = exc
    except Exception as exc:  # recorded; the session is closed and the others go on
        error = f"{job.participant}: {type(exc).__name__}: {exc}"
    finally:
        try:
            session.close()
        except StoreWriteError as exc:
            fault = fault or exc
    if fault is not None:
        raise fault
    return result_from_store(job, store, session.session_id, time.perf_counter() - start, error)


def result_from_store(
    job: ParticipantJob, store: Store, session_id: int, wall_s: float, error: str | None
) -> ParticipantResult:
    """``job``'s result as its session ``session_id`` stands in ``store``."""
    trials = store.trials(session_id=session_id)
    return ParticipantResult(
        index=job.index,
        participant=job.participant,
        status=store.session(job.participant).status,
        trials_completed=sum(t.status == "completed" for t in trials),
        trial_rows=len(trials),
        ratings=len(store.ratings(session_id=session_id)),
        outcomes=dict(Counter(str(t.outcome) for t in trials if t.status == "completed")),
        sim_s=float(sum(t.duration_s or 0.0 for t in trials)),
        wall_s=wall_s,
        error=error,
    )

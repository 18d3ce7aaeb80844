"""Run simulated participants through the real session engine into a study store.

Each participant is enrolled with ``study.session.Session.enrol`` and driven to the end by
``study.headless.run_headless`` - the same state machine, trial loop (``app.trial.Trial``) and
store writes as a live session - with a :class:`~study.simulated.participant.SimulatedParticipant`
as its input and its answers. Headless, as fast as the machine allows.

Determinism: participant ``i`` of a run with seed ``s`` is ``sim<s>-<i+1:03d>``; their
parameters, session seed and schedule row are fixed by ``(s, i)`` and the store's earlier
enrolments (rows are planned in the parent, in index order, with ``study.schedule.next_row``),
so the data do not depend on the number of workers.

Workers (``workers > 1``): processes (``spawn``), each opening its own connection to the same
SQLite WAL store. The store serialises writers with ``BEGIN IMMEDIATE`` and a busy timeout, and
samples are batched by each session's ``SampleWriter``, so concurrent sessions are safe.
"""

from __future__ import annotations

import hashlib
import multiprocessing as mp
import queue
import sys
import time
from collections import Counter
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from study.simulated.errors import SimulationRunError
from study.simulated.population import DEFAULT_POPULATION_PATH, load_population

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


@dataclass(frozen=True)
class SimulationReport:
    """The whole run; ``as_dict`` is what ``python -m study simulate`` prints last."""

    participants: int
    trials: int
    ratings: int
    wall_s: float
    workers: int
    db: str
    seed: int
    outcomes: dict[str, int]
    sim_s: float
    errors: list[str] = field(default_factory=list)
    results: list[ParticipantResult] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {
            "participants": self.participants,
            "trials": self.trials,
            "ratings": self.ratings,
            "wall_s": round(self.wall_s, 3),
            "workers": self.workers,
            "db": self.db,
            "seed": self.seed,
            "simulated_s": round(self.sim_s, 1),
            "outcomes": dict(sorted(self.outcomes.items())),
            "errors": list(self.errors),
        }


def participant_id(index: int, *, seed: int) -> str:
    """``sim<seed>-<index+1:03d>``, e.g. ``sim1-001`` (a valid pseudonymous ID)."""
    return f"sim{seed}-{index + 1:03d}"


def session_seed(index: int, *, seed: int) -> int:
    """The session seed (trial seeds derive from it) of participant ``index`` under ``seed``."""
    return int(np.random.SeedSequence([seed, index, 3]).generate_state(1)[0] >> 1)


def plan_jobs(store: Store, *, n: int, seed: int, first: int = 0) -> list[ParticipantJob]:
    """Participants ``first .. first + n - 1``: IDs, seeds and design rows continuing the store's
    enrolment history in index order. Raises if an ID is already enrolled."""
    from study.schedule import Enrollment, next_row

    with store.transaction() as tx:
        history = tx.enrolment_history()
    taken = {p for p, _, _ in history}
    entries = [
        Enrollment(p, withdrawn=status == "withdrawn", row=row) for p, row, status in history
    ]
    jobs: list[ParticipantJob] = []
    for index in range(first, first + n):
        pid = participant_id(index, seed=seed)
        if pid in taken:
            raise SimulationRunError(
                f"participant {pid} is already in {store.path}; simulate into a new --db, with "
                f"another --seed, or continue numbering with --first {first + n}"
            )
        row = next_row(entries)
        entries.append(Enrollment(pid, withdrawn=False, row=row))
        jobs.append(ParticipantJob(index, pid, row, session_seed(index, seed=seed)))
    return jobs


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
    from study.headless import run_headless
    from study.session import Session
    from study.simulated.participant import SimulatedParticipant

    start = time.perf_counter()
    params = load_population(population_path).draw(job.index, seed=seed)
    person = SimulatedParticipant(params)
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
    except Exception as exc:  # recorded; the session is closed and the others go on
        error = f"{job.participant}: {type(exc).__name__}: {exc}"
    finally:
        session.close()
    return _result(job, store, session.session_id, time.perf_counter() - start, error)


def _result(
    job: ParticipantJob, store: Store, session_id: int, wall_s: float, error: str | None
) -> ParticipantResult:
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


# ---- worker processes ----------------------------------------------------------------------
_worker: dict[str, Any] = {}


def _init_worker(
    protocol_path: str, db: str, population_path: str, seed: int, synchronous: str, progress: Any
) -> None:
    from study.protocol import load_protocol
    from study.session import open_store

    protocol = load_protocol(protocol_path)
    _worker.update(
        protocol=protocol,
        store=open_store(db, protocol, synchronous=synchronous),
        population_path=Path(population_path),
        seed=seed,
        progress=progress,
    )


def _run_in_worker(job: ParticipantJob) -> ParticipantResult:
    progress = _worker["progress"]
    return run_participant(
        job,
        store=_worker["store"],
        protocol=_worker["protocol"],
        population_path=_worker["population_path"],
        seed=_worker["seed"],
        on_trial=lambda: progress.put(1),
    )


# ---- the whole study ---------------------------------------------------------------------
def simulate(
    *,
    protocol_path: str | Path,
    db: str | Path,
    participants: int,
    seed: int,
    workers: int = 1,
    population_path: str | Path = DEFAULT_POPULATION_PATH,
    first: int = 0,
    synchronous: str = "NORMAL",
    progress: bool = True,
) -> SimulationReport:
    """Simulate ``participants`` people through the protocol into the store at ``db``."""
    from tqdm import tqdm

    from study.protocol import load_protocol
    from study.session import open_store

    if participants < 1:
        raise SimulationRunError(f"participants must be at least 1, got {participants}")
    if workers < 1:
        raise SimulationRunError(f"workers must be at least 1, got {workers}")
    for name, value in (("seed", seed), ("first", first)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise SimulationRunError(f"{name} must be an integer >= 0, got {value!r}")
    start = time.perf_counter()
    population_path = Path(population_path)
    load_population(population_path)  # fail early, in the parent, on a bad population file
    protocol = load_protocol(protocol_path)
    Path(db).parent.mkdir(parents=True, exist_ok=True)
    store = open_store(db, protocol, synchronous=synchronous)
    try:
        jobs = plan_jobs(store, n=participants, seed=seed, first=first)
        per_person = protocol.training.runs + len(protocol.tasks) * len(protocol.modes)
        bar = tqdm(
            total=participants * per_person,
            unit="trial",
            desc=f"simulate {participants} participants",
            file=sys.stderr,
            disable=not progress,
        )
        with bar:
            if workers == 1:
                results = [
                    run_participant(
                        job,
                        store=store,
                        protocol=protocol,
                        population_path=population_path,
                        seed=seed,
                        on_trial=lambda: bar.update(1),
                    )
                    for job in jobs
                ]
            else:
                results = _run_pool(
                    jobs,
                    workers=workers,
                    protocol_path=Path(protocol_path),
                    db=Path(db),
                    population_path=population_path,
                    seed=seed,
                    synchronous=synchronous,
                    bar=bar,
                )
    finally:
        store.close()
    results.sort(key=lambda r: r.index)
    outcomes: Counter[str] = Counter()
    for r in results:
        outcomes.update(r.outcomes)
    return SimulationReport(
        participants=len(results),
        trials=sum(r.trial_rows for r in results),
        ratings=sum(r.ratings for r in results),
        wall_s=time.perf_counter() - start,
        workers=workers,
        db=str(db),
        seed=seed,
        outcomes=dict(outcomes),
        sim_s=sum(r.sim_s for r in results),
        errors=[r.error for r in results if r.error],
        results=results,
    )


def _run_pool(
    jobs: list[ParticipantJob],
    *,
    workers: int,
    protocol_path: Path,
    db: Path,
    population_path: Path,
    seed: int,
    synchronous: str,
    bar: Any,
) -> list[ParticipantResult]:
    ctx = mp.get_context("spawn")
    ticks = ctx.Queue()
    results: list[ParticipantResult] = []
    with ProcessPoolExecutor(
        max_workers=min(workers, len(jobs)),
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(str(protocol_path), str(db), str(population_path), seed, synchronous, ticks),
    ) as pool:
        pending: set[Future[ParticipantResult]] = {pool.submit(_run_in_worker, j) for j in jobs}
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            _drain(ticks, bar)
            for future in done:
                results.append(future.result())
        _drain(ticks, bar)
    return results


def _drain(ticks: Any, bar: Any) -> None:
    while True:
        try:
            bar.update(ticks.get_nowait())
        except queue.Empty:
            return

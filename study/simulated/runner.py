"""Run simulated participants through the real session engine into a study store.

Each participant is enrolled with ``study.session.Session.enrol`` and driven to the end by
``study.session.headless.run_headless`` - the same state machine, trial loop (``app.trial.Trial``) and
store writes as a live session - with a :class:`~study.simulated.participant.SimulatedParticipant`
as its input and its answers. Headless, as fast as the machine allows.

Determinism: participant ``i`` of a run with seed ``s`` is ``sim<s>-<i+1:03d>``; their
parameters, session seed and schedule row are fixed by ``(s, i)`` and the store's earlier
enrolments (rows are planned in the parent, in index order, with ``study.schedule.next_row``),
so the data do not depend on the number of workers.

Resuming (``resume=True``, ``python -m study simulate --resume``): a killed run is continued
on the same store with the same arguments. Participants already completed are kept; one left
unfinished (killed mid-session) is deleted and simulated again from the start with the same
design row and session seed, and those never enrolled are run. A simulated person's behaviour
depends on their whole history in the session (learning, fatigue), so redoing them is the only
way the resumed store holds exactly the data an uninterrupted run would (apart from wall-clock
stamps and row ids). Only simulated participants are ever deleted.

A store that stops taking writes (full disk, read-only: ``StoreWriteError``) ends the whole run:
no further participant is started, the report carries the error, and ``resume`` continues once
the disk is fixed.

Engines: the local one (this process or worker processes sharing the store,
:mod:`study.simulated.local_engine`) and the Dask one (:mod:`study.simulated.dask_engine`).
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from study.protocol import load_protocol
from study.schedule import Enrollment, next_row
from study.session import open_store
from study.simulated.dask_engine import run_on_dask
from study.simulated.errors import SimulationRunError
from study.simulated.job import (
    ParticipantJob,
    ParticipantResult,
    result_from_store,
)
from study.simulated.local_engine import LocalRun, run_local
from study.simulated.population import DEFAULT_POPULATION_PATH, load_population

if TYPE_CHECKING:
    from study.protocol import Protocol
    from study.store import Store


ENGINES = ("local", "dask")
"""``local``: this process or worker processes sharing the store; ``dask``: a Dask cluster
returning participants to this process, the store's only writer."""


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
    error: str | None = None
    """Why the run stopped before its end (a store that took no more writes), else ``None``."""
    kept: list[str] = field(default_factory=list)
    """``resume``: participants already completed in the store, left as they were."""
    redone: list[str] = field(default_factory=list)
    """``resume``: unfinished participants deleted and simulated again from the start."""

    def as_dict(self) -> dict[str, Any]:
        extra: dict[str, Any] = {}
        if self.kept or self.redone:
            extra.update(kept=list(self.kept), redone=list(self.redone))
        if self.error is not None:
            extra.update(error=self.error)
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
            **extra,
        }


def participant_id(index: int, *, seed: int) -> str:
    """``sim<seed>-<index+1:03d>``, e.g. ``sim1-001`` (a valid pseudonymous ID)."""
    return f"sim{seed}-{index + 1:03d}"


def session_seed(index: int, *, seed: int) -> int:
    """The session seed (trial seeds derive from it) of participant ``index`` under ``seed``."""
    return int(np.random.SeedSequence([seed, index, 3]).generate_state(1)[0] >> 1)


@dataclass(frozen=True)
class SimulationPlan:
    """What a run (or a resumed run) does: ``jobs`` to simulate (``redo``: IDs among them to
    delete first) and ``kept``: participants already completed, with their session ids."""

    jobs: list[ParticipantJob]
    redo: list[str] = field(default_factory=list)
    kept: list[tuple[ParticipantJob, int]] = field(default_factory=list)


def plan_jobs(store: Store, *, n: int, seed: int, first: int = 0) -> list[ParticipantJob]:
    """Participants ``first .. first + n - 1`` for a new run (``plan_run`` without resuming):
    raises if an ID is already enrolled."""
    return plan_run(store, n=n, seed=seed, first=first).jobs


def plan_run(
    store: Store, *, n: int, seed: int, first: int = 0, resume: bool = False
) -> SimulationPlan:
    """Participants ``first .. first + n - 1``: IDs, seeds and design rows continuing the store's
    enrolment history in index order.

    Without ``resume`` an ID already enrolled is an error. With ``resume`` the design rows are
    planned from the history as it stood before the first of these participants was enrolled,
    which is what the interrupted run planned, and every enrolled participant's stored row and
    seed must match that plan (else this is not the same run: wrong ``--seed`` or ``--first``)."""

    ids = [participant_id(index, seed=seed) for index in range(first, first + n)]
    with store.transaction() as tx:
        history = tx.enrolment_history()
    enrolled = {p: (row, status) for p, row, status in history}
    if not resume:
        taken = [pid for pid in ids if pid in enrolled]
        if taken:
            raise SimulationRunError(
                f"participant {taken[0]} is already in {store.path}; continue a killed run with "
                f"--resume, or simulate into a new --db, with another --seed, or continue "
                f"numbering with --first {first + n}"
            )
    ours = set(ids)
    cut = next((k for k, (p, _, _) in enumerate(history) if p in ours), len(history))
    entries = [
        Enrollment(p, withdrawn=status == "withdrawn", row=row) for p, row, status in history[:cut]
    ]
    plan = SimulationPlan(jobs=[])
    for index, pid in zip(range(first, first + n), ids, strict=True):
        row = next_row(entries)
        entries.append(Enrollment(pid, withdrawn=False, row=row))
        job = ParticipantJob(index, pid, row, session_seed(index, seed=seed))
        if pid not in enrolled:
            plan.jobs.append(job)
            continue
        _check_resumable(store, job, stored_row=enrolled[pid][0])
        if enrolled[pid][1] == "completed":
            plan.kept.append((job, store.session(pid).session_id))
        else:
            plan.jobs.append(job)
            plan.redo.append(pid)
    return plan


def _check_resumable(store: Store, job: ParticipantJob, *, stored_row: int) -> None:
    """Refuse to resume over a participant this run would not have made identically."""
    demographics = store.demographics(job.participant) or {}
    session = store.session(job.participant)
    if not demographics.get("simulated"):
        raise SimulationRunError(
            f"participant {job.participant} in {store.path} is not a simulated participant; "
            "--resume only continues simulated runs and never touches other data"
        )
    if (stored_row, session.seed) != (job.schedule_row, job.session_seed):
        raise SimulationRunError(
            f"participant {job.participant} in {store.path} was enrolled with design row "
            f"{stored_row} and session seed {session.seed}, but this run plans row "
            f"{job.schedule_row} and seed {job.session_seed}: it is not the run being resumed; "
            "use the original --seed, --first and --participants"
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
    resume: bool = False,
    engine: str = "local",
    scheduler: str | None = None,
    client: Any = None,
) -> SimulationReport:
    """Simulate ``participants`` people through the protocol into the store at ``db``;
    ``resume`` continues a killed run with the same arguments (see module docstring).

    ``engine="local"`` runs in this process (``workers == 1``) or in ``workers`` worker
    processes sharing the store; ``engine="dask"`` runs on the Dask scheduler at ``scheduler``
    or, without one, on a new ``LocalCluster`` of ``workers`` processes, with this process the
    store's only writer (``study.simulated.dask_engine``). Both write the same data.
    ``client``: with ``engine="dask"``, a connected ``distributed.Client`` to run on instead of
    connecting anew (a sweep runs many simulations on one cluster).

    A store that takes no more writes stops the run: the report's ``error`` says why, and the
    participants finished before it are in ``results``."""

    _check_arguments(
        participants=participants,
        workers=workers,
        engine=engine,
        remote=scheduler is not None or client is not None,
        seed=seed,
        first=first,
    )
    start = time.perf_counter()
    population_path = Path(population_path)
    load_population(population_path)  # fail early, in the parent, on a bad population file
    protocol = load_protocol(protocol_path)
    store = _store(db, protocol, resume=resume, synchronous=synchronous)
    results: list[ParticipantResult] = []
    fault: str | None = None
    try:
        plan = plan_run(store, n=participants, seed=seed, first=first, resume=resume)
        for pid in plan.redo:
            store.discard_participant(pid)
        results += [result_from_store(job, store, sid, 0.0, None) for job, sid in plan.kept]
        if plan.jobs:
            run = LocalRun(Path(protocol_path), Path(db), population_path, seed, synchronous)
            fault = _run_jobs(
                plan.jobs,
                results,
                run=run,
                engine=engine,
                store=store,
                protocol=protocol,
                workers=workers,
                progress=progress,
                scheduler=scheduler,
                client=client,
                desc=f"simulate {participants} participants",
            )
    finally:
        store.close()
    return _report(
        results,
        plan,
        wall_s=time.perf_counter() - start,
        workers=workers,
        db=str(db),
        seed=seed,
        fault=fault,
    )


def _run_jobs(
    jobs: list[ParticipantJob],
    results: list[ParticipantResult],
    *,
    run: LocalRun,
    engine: str,
    store: Store,
    protocol: Protocol,
    workers: int,
    progress: bool,
    scheduler: str | None,
    client: Any,
    desc: str,
) -> str | None:
    """``jobs`` on ``engine``, appending to ``results``; the store fault that stopped the run,
    else ``None``."""
    per_person = protocol.training.runs + len(protocol.tasks) * len(protocol.modes)
    if engine == "dask":
        return run_on_dask(
            jobs,
            results,
            store=store,
            protocol_path=run.protocol_path,
            population_path=run.population_path,
            seed=run.seed,
            workers=workers,
            scheduler=scheduler,
            trials_each=per_person,
            progress=progress,
            client=client,
        )
    return run_local(
        jobs,
        results,
        run=run,
        store=store,
        protocol=protocol,
        workers=workers,
        progress=progress,
        trials_each=per_person,
        desc=desc,
    )


def _store(db: str | Path, protocol: Protocol, *, resume: bool, synchronous: str) -> Store:
    """The store to simulate into (its folder made; ``resume``: it must exist)."""
    if resume and not Path(db).is_file():
        raise SimulationRunError(f"no store at {db}; --resume continues a run in its store")
    Path(db).parent.mkdir(parents=True, exist_ok=True)
    return open_store(db, protocol, synchronous=synchronous)


def _check_arguments(
    *, participants: int, workers: int, engine: str, remote: bool, seed: int, first: int
) -> None:
    """Refuse arguments ``simulate`` cannot run with, before any file is touched."""
    if participants < 1:
        raise SimulationRunError(f"participants must be at least 1, got {participants}")
    if workers < 1:
        raise SimulationRunError(f"workers must be at least 1, got {workers}")
    if engine not in ENGINES:
        raise SimulationRunError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if remote and engine != "dask":
        raise SimulationRunError("--scheduler needs --engine dask (the local engine has none)")
    for name, value in (("seed", seed), ("first", first)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise SimulationRunError(f"{name} must be an integer >= 0, got {value!r}")


def _report(
    results: list[ParticipantResult],
    plan: SimulationPlan,
    *,
    wall_s: float,
    workers: int,
    db: str,
    seed: int,
    fault: str | None,
) -> SimulationReport:
    """The run's report: ``results`` in participant order, their trials, ratings and outcomes."""
    results.sort(key=lambda r: r.index)
    outcomes: Counter[str] = Counter()
    for r in results:
        outcomes.update(r.outcomes)
    return SimulationReport(
        participants=len(results),
        trials=sum(r.trial_rows for r in results),
        ratings=sum(r.ratings for r in results),
        wall_s=wall_s,
        workers=workers,
        db=db,
        seed=seed,
        outcomes=dict(outcomes),
        sim_s=sum(r.sim_s for r in results),
        errors=[r.error for r in results if r.error],
        results=results,
        error=fault,
        kept=[job.participant for job, _ in plan.kept],
        redone=list(plan.redo),
    )

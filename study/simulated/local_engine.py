"""The local engine: simulated participants in this process, or in ``workers`` worker processes
writing the same store.

Workers (``workers > 1``): processes forked warm from a server that imported the simulation
once (:mod:`study.simulated.warm_start`), each opening its own connection to the same
SQLite WAL store. The store serialises writers with ``BEGIN IMMEDIATE`` and a busy timeout, and
samples are batched by each session's ``SampleWriter``, so concurrent sessions are safe. The
Dask engine beside it (:mod:`study.simulated.dask_engine`) writes the same data.
"""

from __future__ import annotations

import queue
import sys
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from study.protocol import load_protocol
from study.session import open_store
from study.simulated.job import ParticipantJob, ParticipantResult, run_participant
from study.simulated.warm_start import LOCAL, forkserver
from study.store import StoreWriteError

if TYPE_CHECKING:
    from study.protocol import Protocol
    from study.store import Store


@dataclass(frozen=True)
class LocalRun:
    """What a run's participants are made from and written to; a worker process rebuilds its
    protocol, store and population from it (paths and numbers: it crosses to a new process)."""

    protocol_path: Path
    db: Path
    population_path: Path
    seed: int
    synchronous: str = "FULL"


def run_local(
    jobs: list[ParticipantJob],
    results: list[ParticipantResult],
    *,
    run: LocalRun,
    store: Store,
    protocol: Protocol,
    workers: int,
    progress: bool,
    trials_each: int,
    desc: str,
) -> str | None:
    """The local engine: ``jobs`` in this process, or in ``workers`` processes writing the same
    store; returns the store fault that stopped the run, else ``None``."""

    fault: str | None = None
    # overall: participants done; below it the trials, of the participant running in this
    # process, or of all of them with worker processes (their ticks arrive without a name)
    people = tqdm(
        total=len(jobs),
        unit="participant",
        desc=desc,
        file=sys.stderr,
        disable=not progress,
        position=0,
    )
    bar = tqdm(
        total=(len(jobs) if workers > 1 else 1) * trials_each,
        unit="trial",
        desc="  trials",
        file=sys.stderr,
        disable=not progress,
        position=1,
        leave=False,
    )
    with people, bar:
        if workers > 1:
            return _run_pool(jobs, results, run=run, workers=workers, bar=bar, people=people)
        try:
            for job in jobs:
                bar.reset()
                bar.set_description(f"  {job.participant}")
                results.append(
                    run_participant(
                        job,
                        store=store,
                        protocol=protocol,
                        population_path=run.population_path,
                        seed=run.seed,
                        on_trial=lambda: bar.update(1),
                    )
                )
                people.update(1)
        except StoreWriteError as exc:
            fault = str(exc)
    return fault


def _run_pool(
    jobs: list[ParticipantJob],
    results: list[ParticipantResult],
    *,
    run: LocalRun,
    workers: int,
    bar: Any,
    people: Any,
) -> str | None:
    """Run ``jobs`` in worker processes, appending to ``results``; returns the store fault that
    stopped the run (queued participants are then not started), else ``None``."""

    ctx = forkserver(LOCAL)
    ticks = ctx.Queue()
    fault: str | None = None
    with ProcessPoolExecutor(
        max_workers=min(workers, len(jobs)),
        mp_context=ctx,
        initializer=_init_worker,
        initargs=(run, ticks),
    ) as pool:
        pending: set[Future[ParticipantResult]] = {pool.submit(_run_in_worker, j) for j in jobs}
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            _drain(ticks, bar)
            for future in done:
                if future.cancelled():
                    continue
                try:
                    results.append(future.result())
                    people.update(1)
                except StoreWriteError as exc:
                    fault = fault or str(exc)
                    for other in pending:
                        other.cancel()
        _drain(ticks, bar)
    return fault


def _drain(ticks: Any, bar: Any) -> None:
    while True:
        try:
            bar.update(ticks.get_nowait())
        except queue.Empty:
            return


# ---- worker processes ----------------------------------------------------------------------
_worker: dict[str, Any] = {}


def _init_worker(run: LocalRun, progress: Any) -> None:
    protocol = load_protocol(run.protocol_path)
    _worker.update(
        protocol=protocol,
        store=open_store(run.db, protocol, synchronous=run.synchronous, verify=False),  # checked
        population_path=run.population_path,
        seed=run.seed,
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

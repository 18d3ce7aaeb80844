"""Simulated participants on a Dask cluster (``python -m study simulate --engine dask``).

Why Dask: a lab running thousands of simulated participants wants an engine that is kept up by
others, runs on a laptop (``LocalCluster``), a lab server or a batch system (dask-jobqueue),
shows what it does, and survives a worker that dies. Our own process pool does none of the last
three.

How: every participant is one task (:func:`simulate_remote`). The task receives the protocol
and population files' *text* (workers need not see the client's files), simulates the
participant into a private scratch store in the worker's own directory (Dask's
``local_directory``: with Dask's file locking on, as by default, a killed worker's is purged by
the next worker that starts on that host, so no partial store is left behind; put it on a local
disk, as Dask advises, not a network file system: SQLite writes there), and returns a
:class:`~study.simulated.bundle.ParticipantBundle`. The client is the study store's only writer:
it merges bundles in participant order (a bundle finished early waits on its worker for those
before it), one transaction each. Hence

- the store holds exactly what a 1-worker local run with the same seed writes (each
  participant's seeds and design row are planned up front, ``runner.plan_run``);
- a worker lost mid-participant loses nothing: the scheduler re-runs its tasks on another worker
  (up to ``distributed.scheduler.allowed-failures`` times) and only the bundle that arrives is
  written, once;
- Ctrl-C (``KeyboardInterrupt``) leaves only whole participants in the store: those merged
  before it; ``--resume`` plans the rest.

Progress: per-trial ticks travel from workers to the client as Dask events (``log_event`` on
the topic :data:`PROGRESS_TOPIC`); the client shows an overall bar (participants written) and
one bar per participant in flight (at most :data:`MAX_PARTICIPANT_BARS`).
"""

from __future__ import annotations

import logging
import sys
import tempfile
import threading
import uuid
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from study.protocol import load_protocol
from study.session import open_store
from study.simulated.bundle import ParticipantBundle, merge_bundle, read_bundle_file
from study.simulated.errors import SchedulerUnreachableError, SimulationRunError
from study.simulated.job import run_participant
from study.simulated.warm_start import dask_forkserver
from study.store import StoreWriteError

if TYPE_CHECKING:
    from distributed import Client

    from study.simulated.job import ParticipantJob, ParticipantResult
    from study.store import Store

CONNECT_TIMEOUT_S = 5.0
"""How long to try an existing scheduler before saying it cannot be reached."""

PROGRESS_TOPIC = "study-simulate-progress"
MAX_PARTICIPANT_BARS = 8
"""More in-flight participants than this are counted in the overall bar only (a cluster with
hundreds of workers would otherwise fill the terminal)."""


@dataclass(frozen=True)
class RunInputs:
    """Everything a worker needs besides the job, as text (no shared file system assumed)."""

    protocol_name: str
    protocol_text: str
    population_name: str
    population_text: bytes
    seed: int
    run_token: str
    """Distinguishes this run's progress events from another run's on the same cluster."""


def simulate_remote(job: ParticipantJob, inputs: RunInputs) -> ParticipantBundle:
    """The task: simulate ``job``'s participant into a scratch store; return it as a bundle."""

    worker = _current_worker()
    trials = 0

    def tick() -> None:
        nonlocal trials
        trials += 1
        if worker is not None:
            worker.log_event(PROGRESS_TOPIC, (inputs.run_token, job.participant, trials))

    # in the worker's own directory: one killed mid-participant leaves nothing in the system's
    # temporary folder (Dask purges a dead worker's directory when the next worker starts)
    local = None if worker is None else worker.local_directory
    with tempfile.TemporaryDirectory(prefix=f"simulate-{job.participant}-", dir=local) as scratch:
        folder = Path(scratch)
        protocol_path = folder / inputs.protocol_name
        protocol_path.write_text(inputs.protocol_text, encoding="utf-8")
        population_path = folder / inputs.population_name  # its name and hash are recorded
        population_path.write_bytes(inputs.population_text)
        protocol = load_protocol(protocol_path)
        db = folder / "participant.db"
        store = open_store(db, protocol, synchronous="NORMAL")
        try:
            result = run_participant(
                job,
                store=store,
                protocol=protocol,
                population_path=population_path,
                seed=inputs.seed,
                on_trial=tick,
            )
        finally:
            store.close()
        return ParticipantBundle(result=result, db=read_bundle_file(str(db)))


def _current_worker() -> Any:
    from distributed import get_worker

    try:
        return get_worker()
    except ValueError:  # run outside a worker (a unit test calling the task directly)
        return None


def connect(*, scheduler: str | None, workers: int, stack: ExitStack) -> Client:
    """A client on the scheduler at ``scheduler``, or on a new ``LocalCluster`` of ``workers``
    single-threaded processes (the simulation holds the GIL; started warm,
    :func:`~study.simulated.warm_start.dask_forkserver`); closed with ``stack``."""
    from distributed import Client, LocalCluster

    if scheduler is None:
        dask_forkserver()
        cluster = stack.enter_context(
            LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # a free port: never collides with another run
                silence_logs=logging.ERROR,
            )
        )
        return stack.enter_context(Client(cluster))
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError) as exc:
        raise SchedulerUnreachableError(
            f"cannot reach the Dask scheduler at {scheduler} within {CONNECT_TIMEOUT_S:g} s "
            f"({type(exc).__name__}: {exc}); check the address (tcp://HOST:PORT, as printed by "
            "`dask scheduler`) and that the scheduler runs and its port is open from here, or "
            "leave out --scheduler to use a cluster on this machine"
        ) from None
    return stack.enter_context(client)


class _Bars:
    """The overall bar (participants written) and one bar per participant in flight."""

    def __init__(self, *, total: int, trials_each: int, enabled: bool, run_token: str) -> None:

        self._tqdm = tqdm
        self._lock = threading.Lock()
        self._enabled = enabled
        self._trials_each = trials_each
        self._token = run_token
        self._bars: dict[str, tuple[Any, int]] = {}
        """participant -> (their bar, its terminal line)"""
        self._free = list(range(MAX_PARTICIPANT_BARS, 0, -1))
        self.overall = tqdm(
            total=total,
            unit="participant",
            desc="participants written",
            file=sys.stderr,
            disable=not enabled,
            position=0,
        )

    def on_event(self, event: tuple[float, Any]) -> None:
        """Dask event handler (runs on the client's event-loop thread)."""
        token, participant, trials = event[1]
        if token != self._token or not self._enabled:
            return
        with self._lock:
            if participant not in self._bars:
                if not self._free:
                    return
                position = self._free.pop()
                bar = self._tqdm(
                    total=self._trials_each,
                    unit="trial",
                    desc=f"  {participant}",
                    file=sys.stderr,
                    position=position,
                    leave=False,
                )
                self._bars[participant] = (bar, position)
            bar, _ = self._bars[participant]
            if trials < bar.n:  # re-run after its worker was lost: counts again from 0
                bar.reset()
            bar.update(trials - bar.n)

    def written(self, participant: str) -> None:
        with self._lock:
            entry = self._bars.pop(participant, None)
            if entry is not None:
                entry[0].close()
                self._free.append(entry[1])
            self.overall.update(1)

    def close(self) -> None:
        with self._lock:
            for bar, _ in self._bars.values():
                bar.close()
            self._bars.clear()
            self.overall.close()


def run_on_dask(
    jobs: list[ParticipantJob],
    results: list[ParticipantResult],
    *,
    store: Store,
    protocol_path: Path,
    population_path: Path,
    seed: int,
    workers: int,
    scheduler: str | None,
    trials_each: int,
    progress: bool,
    client: Client | None = None,
) -> str | None:
    """Run ``jobs`` as Dask tasks and merge each participant into ``store`` in job order,
    appending to ``results``; returns the store fault that stopped the run, else ``None``.

    A participant the worker could not store (its own disk full) is a fault too: the run stops,
    queued participants are cancelled, and ``--resume`` continues once the disk is fixed.
    ``client``: an already-connected client to use (a sweep shares one across its runs);
    ``scheduler`` and ``workers`` are then ignored."""

    inputs = RunInputs(
        protocol_name=protocol_path.name,
        protocol_text=protocol_path.read_text(encoding="utf-8"),
        population_name=population_path.name,
        population_text=population_path.read_bytes(),
        seed=seed,
        run_token=uuid.uuid4().hex,
    )
    with ExitStack() as stack:
        if client is None:
            client = connect(scheduler=scheduler, workers=workers, stack=stack)
        bars = _Bars(
            total=len(jobs), trials_each=trials_each, enabled=progress, run_token=inputs.run_token
        )
        stack.callback(bars.close)
        client.subscribe_topic(PROGRESS_TOPIC, bars.on_event)
        stack.callback(client.unsubscribe_topic, PROGRESS_TOPIC)
        futures = [
            client.submit(
                simulate_remote,
                job,
                inputs,
                key=f"simulate-{job.participant}-{inputs.run_token}",
                pure=False,
            )
            for job in jobs
        ]
        outstanding = dict(enumerate(futures))
        stack.callback(lambda: client.cancel(list(outstanding.values())))
        # In job order: a bundle finished early waits on its worker (Dask spills it to disk if
        # memory runs short) rather than in this process, and is released once merged.
        for k, (job, future) in enumerate(zip(jobs, futures, strict=True)):
            try:
                bundle: ParticipantBundle = future.result()
            except StoreWriteError as exc:  # the worker's scratch disk
                return str(exc)
            except Exception as exc:
                raise SimulationRunError(
                    f"{job.participant} could not be simulated on the Dask cluster "
                    f"({type(exc).__name__}: {exc}); check that every worker runs this platform "
                    "(same version) with a writable temporary folder, then continue with --resume"
                ) from exc
            try:
                merge_bundle(store, bundle)
            except StoreWriteError as exc:
                return str(exc)
            del outstanding[k]
            future.release()
            results.append(bundle.result)
            bars.written(job.participant)
    return None

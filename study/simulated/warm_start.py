"""Worker processes that start warm: forked from a server that imported the simulation once.

A ``spawn``-ed worker imports numpy, MuJoCo, pinocchio, numba's kernels and the study's modules
again, about 2 CPU s each before its first tick. ``multiprocessing``'s ``forkserver`` forks every
worker from one server process instead, which imports :data:`LOCAL`'s modules (or
:data:`DASK`'s) once, when the first worker starts: a pool of N pays one import, not N, and a
worker restarted after a crash starts in milliseconds.

What a worker gets is what a spawned one gets: the server is a fresh single-threaded process
(not a fork of the caller, so it holds none of the caller's locks, threads or open stores); each
worker takes the caller's ``sys.path`` and working folder at its own start. Its environment is
the caller's when the server started (the first worker of the process).

The server is one per process and keeps the modules of the first call that started it: a later
call with another list gets workers that import the rest themselves, as spawned ones do.
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Sequence
from multiprocessing.context import BaseContext

__all__ = ["DASK", "LOCAL", "dask_forkserver", "forkserver"]

LOCAL = ("study.simulated.local_engine",)
"""What a local-engine worker runs (:mod:`study.simulated.local_engine` imports the simulation)."""

DASK = ("distributed", "study.simulated.dask_engine", "study.simulated.job")
"""What a Dask worker runs: Dask's worker, and the task's modules (which it would import on the
first participant)."""


def forkserver(modules: Sequence[str] = LOCAL) -> BaseContext:
    """The ``forkserver`` context, its server (when it starts) importing ``modules`` first."""
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(modules))
    return ctx


def dask_forkserver() -> None:
    """From now on in this process, Dask's ``LocalCluster`` and nannies start their workers from
    the forkserver with :data:`DASK` preloaded (Dask's default is ``spawn``; its own forkserver
    setting preloads Dask's packages only: ours are set after it, and include them)."""
    import dask
    from distributed.utils import get_mp_context

    dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"})
    get_mp_context()  # Dask's preload now, so that it does not replace ours at the first worker
    forkserver(DASK)

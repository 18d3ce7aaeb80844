"""Simulation workers start warm: forked from a server that imported the simulation once."""

from __future__ import annotations

import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.context import BaseContext

from study.simulated.warm_start import LOCAL, forkserver
from tests.support.import_probe import cpu_to_import


def _imports(ctx: BaseContext, n: int) -> list[tuple[float, bool]]:
    with ProcessPoolExecutor(max_workers=2, mp_context=ctx) as pool:
        jobs = [
            pool.submit(cpu_to_import, "study.simulated.local_engine", already="mujoco")
            for _ in range(n)
        ]
        return [j.result() for j in jobs]


def test_each_pool_worker_has_the_simulation_imported_before_its_first_participant() -> None:
    for _ in range(2):  # a second pool in the same process forks from the same server
        for cpu, had_mujoco in _imports(forkserver(LOCAL), 4):
            assert had_mujoco
            assert cpu < 0.2, f"a worker took {cpu:.2f} CPU s to import the engine"


def test_a_spawned_worker_would_import_it_first() -> None:
    """What the warm start saves (and what the test above would see without it)."""
    cpu, had_mujoco = _imports(mp.get_context("spawn"), 1)[0]
    assert not had_mujoco and cpu > 0.5

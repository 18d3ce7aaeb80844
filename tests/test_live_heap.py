"""A served trial's memory stays flat: every tick goes to the store, none stays in the process.

A live session's control loop is driven by hand (the server's own tick: ``LiveRun``'s step,
through the trial, the sample writer, the view's snapshot and the console's plots), as fast as
it goes instead of at 100 Hz. Once the bounded buffers are full (the console's plot window of
``PLOT_WINDOW`` ticks), 2,000 more ticks may leave neither memory (tracemalloc) nor objects
for the garbage collector to walk behind: a trial that kept its tick records (main before
``Trial(keep_records=False)``) grew by 2.75 MB here, 1.4 kB and one tracked object a tick (0.3
MB/s with two trials served, and ever longer full collections: ``benchmarks/server_memory.py``).
"""

from __future__ import annotations

import gc
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from study.protocol import load_protocol
from study.server.live import LiveSession, live_run
from study.server.live.console import PLOT_WINDOW
from study.session import Session, open_store
from tests.protocol_copies import short_protocol

SPAN = 2000
"""Ticks measured after the warm-up."""
MAX_BYTES_PER_TICK = 100
"""Allowed growth: a kept tick record is ~1,400 bytes (the branch: 15-23)."""
MAX_OBJECTS_PER_TICK = 0.1
"""Allowed growth of tracked objects: a kept tick record is one (or two, with its events)."""


class ManualLoop:
    """Stands in for the control loop's ``PacedLoop``: no thread; the test calls ``step``."""

    def __init__(
        self,
        step: Callable[[], bool | None],
        *,
        rate_hz: float,
        name: str,
        on_start: Callable[[], None] | None = None,
    ) -> None:
        self.step = step
        self.rate_hz = rate_hz
        self.name = name

    def start(self) -> ManualLoop:
        return self

    def stop(self, *, timeout: float = 2.0) -> None:
        pass


def _heap(session: Session, ticks: int) -> tuple[int, int]:
    """(bytes traced, objects the collector tracks) once the sample writer has committed all
    ``ticks`` rows (none waits in its buffer), after a full collection."""
    deadline = time.monotonic() + 10
    while session.sample_stats.rows < ticks and time.monotonic() < deadline:
        time.sleep(0.01)
    assert session.sample_stats.rows == ticks, "the sample writer did not keep up"
    gc.collect()
    return tracemalloc.get_traced_memory()[0], len(gc.get_objects())


def test_a_served_trial_leaves_no_memory_behind_per_tick(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(live_run, "PacedLoop", ManualLoop)
    protocol = load_protocol(short_protocol(tmp_path, time_limit_s=600, training_runs=1))
    store = open_store(tmp_path / "study.db", protocol)
    live = LiveSession(Session.enrol(store, protocol, "P01", seed=1), code="1234", title="t")
    try:
        live.session.start()
        live.agree()
        live.start_trial()
        loop = live.trial_run.control
        assert isinstance(loop, ManualLoop), "the live run no longer ticks through PacedLoop"
        k = 0

        def ticks(n: int) -> None:
            nonlocal k
            for _ in range(n):
                k += 1
                if k % 3 == 0:  # a drag: poses at a third of the control rate
                    live.input.on_target(
                        np.array([0.45 + 0.05 * np.sin(k / 90), 0.05 * np.cos(k / 120), 0.3])
                    )
                assert loop.step() is not False, "the trial ended: lengthen its time limit"

        tracemalloc.start(1)
        try:
            ticks(PLOT_WINDOW + 200)  # the plots' window full, every cache warm
            bytes0, objects0 = _heap(live.session, k)
            ticks(SPAN)
            bytes1, objects1 = _heap(live.session, k)
        finally:
            tracemalloc.stop()
        assert live.run is not None and live.run.ticks == k and not live.run.over
    finally:
        live.close()
        store.close()
    assert (bytes1 - bytes0) / SPAN < MAX_BYTES_PER_TICK, f"{bytes1 - bytes0} bytes grown"
    assert (objects1 - objects0) / SPAN < MAX_OBJECTS_PER_TICK, f"{objects1 - objects0} objects"

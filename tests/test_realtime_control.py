"""``serve --realtime``: the server in the kernel's real-time class, control loops and sample
committer above the rest."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from study import scheduling
from study.server.loop import PacedLoop
from study.session import sample_committer
from tests.browser.harness import start_server, wait_until


def _policy(loop: PacedLoop | threading.Thread) -> tuple[int, int]:
    thread = loop if isinstance(loop, threading.Thread) else loop._thread
    tid = thread.native_id
    assert tid is not None
    return os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority


@pytest.fixture
def allowed() -> bool:
    ok = scheduling.set_realtime(7)
    yield ok
    scheduling.set_realtime(None)


def test_a_live_trials_control_loop_and_committer_run_above_the_rest_of_the_server(
    tmp_path: Path, allowed: bool
) -> None:
    rs = start_server(tmp_path, time_limit_s=60.0, training_runs=1)
    try:
        code = rs.server.enrol("P01")
        rs.server.act(code, "start")
        live = rs.server.session(code)
        live.session.agree()
        live.start_trial()
        assert wait_until(lambda: live.control_loop is not None, timeout=30)
        control = live.control_loop
        assert wait_until(lambda: control.ticks > 10, timeout=10)
        assert _policy(control) == ((os.SCHED_RR, 7) if allowed else (os.SCHED_OTHER, 0))
        # this server's committer (a worker's earlier tests may have left theirs to other stores)
        committers = [
            c._thread for c in list(sample_committer._REGISTRY.values()) if c._store is rs.store
        ]
        assert committers and all(
            _policy(t) == ((os.SCHED_RR, 7) if allowed else (os.SCHED_OTHER, 0)) for t in committers
        )
        render = live.view._loop  # started by the server, keeps no time
        assert render is not None
        assert _policy(render) == ((os.SCHED_RR, 1) if allowed else (os.SCHED_OTHER, 0))
    finally:
        rs.stop()


def test_without_a_setting_control_threads_stay_ordinary() -> None:
    scheduling.set_realtime(None)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
    loop = PacedLoop(lambda: None, rate_hz=100.0, on_start=scheduling.enter_timekeeping).start()
    try:
        assert wait_until(lambda: loop.ticks > 3, timeout=5)
        assert _policy(loop) == (os.SCHED_OTHER, 0)
    finally:
        loop.stop()


def test_a_priority_outside_the_kernels_range_is_refused() -> None:
    for wrong in (1, 100):
        with pytest.raises(scheduling.SchedulingError, match=r"2\.\.99"):
            scheduling.set_realtime(wrong)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER

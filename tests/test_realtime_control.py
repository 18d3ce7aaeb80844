"""``serve --realtime``: the server in the kernel's real-time class, its control loops above the rest."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from study.server import realtime
from study.server.loop import PacedLoop
from tests.browser.harness import start_server, wait_until


def _policy(loop: PacedLoop) -> tuple[int, int]:
    tid = loop._thread.native_id
    assert tid is not None
    return os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority


@pytest.fixture
def allowed() -> bool:
    ok = realtime.set_realtime(7)
    yield ok
    realtime.set_realtime(None)


def test_a_live_trials_control_loop_runs_above_the_rest_of_the_real_time_server(
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
        render = live.view._loop  # started by the server, not a control thread
        assert render is not None
        assert _policy(render) == ((os.SCHED_RR, 1) if allowed else (os.SCHED_OTHER, 0))
    finally:
        rs.stop()


def test_without_a_setting_control_threads_stay_ordinary() -> None:
    realtime.set_realtime(None)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
    loop = PacedLoop(lambda: None, rate_hz=100.0, on_start=realtime.enter_control).start()
    try:
        assert wait_until(lambda: loop.ticks > 3, timeout=5)
        assert _policy(loop) == (os.SCHED_OTHER, 0)
    finally:
        loop.stop()


def test_a_priority_outside_the_kernels_range_is_refused() -> None:
    for wrong in (1, 100):
        with pytest.raises(ValueError, match=r"2\.\.99"):
            realtime.set_realtime(wrong)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER

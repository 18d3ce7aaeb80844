"""``serve --realtime``: the control loops, and only they, run in the kernel's real-time class."""

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
    ok = realtime.set_control_realtime(7)
    yield ok
    realtime.set_control_realtime(None)


def test_a_live_trials_control_loop_runs_real_time_and_its_renderer_does_not(
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
        expected = (os.SCHED_RR, 7) if allowed else (os.SCHED_OTHER, 0)
        assert _policy(control) == expected
        # the caller's own thread was put back after the permission check
        assert os.sched_getscheduler(0) == os.SCHED_OTHER
        render = live.view._loop
        assert render is not None and _policy(render) == (os.SCHED_OTHER, 0)
    finally:
        rs.stop()


def test_without_a_setting_control_threads_stay_ordinary() -> None:
    realtime.set_control_realtime(None)
    loop = PacedLoop(lambda: None, rate_hz=100.0, on_start=realtime.enter_control).start()
    try:
        assert wait_until(lambda: loop.ticks > 3, timeout=5)
        assert _policy(loop) == (os.SCHED_OTHER, 0)
    finally:
        loop.stop()


def test_a_priority_outside_the_kernels_range_is_refused() -> None:
    with pytest.raises(ValueError, match="1..99"):
        realtime.set_control_realtime(100)

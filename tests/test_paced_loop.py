"""The paced loop holds its rate on the monotonic clock, pauses and survives a failing step."""

from __future__ import annotations

import time

import pytest

from study.server.loop import LoopError, PacedLoop


def wait_until_stopped(loop: PacedLoop, timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while loop.alive and time.monotonic() < deadline:
        time.sleep(0.01)


def test_the_loop_runs_at_its_rate_not_free_running() -> None:
    # the precise figure (and its p99) is benchmarks/control_loop.py's job; this checks pacing
    loop = PacedLoop(lambda: None, rate_hz=200.0).start()
    time.sleep(1.2)
    hz = loop.achieved_hz(window_s=1.0)
    loop.stop()
    assert abs(hz - 200.0) / 200.0 < 0.1, hz


def test_pause_stops_calls_and_resume_restarts_them() -> None:
    calls: list[float] = []
    loop = PacedLoop(lambda: calls.append(time.monotonic()), rate_hz=100.0).start()
    time.sleep(0.2)
    loop.pause()
    time.sleep(0.05)
    n = len(calls)
    time.sleep(0.2)
    assert len(calls) == n
    loop.resume()
    time.sleep(0.2)
    loop.stop()
    assert len(calls) > n + 10


def test_step_returning_false_ends_the_loop_and_errors_are_kept() -> None:
    count = iter(range(5))
    loop = PacedLoop(lambda: next(count) < 3, rate_hz=500.0).start()
    wait_until_stopped(loop)
    assert not loop.alive and loop.ticks == 4

    def boom() -> None:
        raise ValueError("bad tick")

    failing = PacedLoop(boom, rate_hz=500.0).start()
    wait_until_stopped(failing)
    assert not failing.alive and isinstance(failing.error, ValueError)


def test_non_positive_rate_is_refused() -> None:
    with pytest.raises(LoopError, match="rate_hz"):
        PacedLoop(lambda: None, rate_hz=0)

"""The console's data without a browser: a session a server restart left is offered for reopening
and continues; actions needing a reason refuse an empty one (nothing filled in); the condition
line never says "attempt None"; session time counts from the start; the study's progress and the
timeline come from the store. (tests/browser/test_console_day.py uses it all in Chromium.)"""

from __future__ import annotations

import threading
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from study.server.live import session_factory
from study.server.live.console import LivePlots
from study.server.server import ServerError, StudyServer
from study.session import MissingReasonError, open_store
from tests.browser.harness import start_server, wait_until


def _answer(live) -> None:  # type: ignore[no-untyped-def]
    live.answer({i.id: 4 for i in live.session.screen().items})


def test_an_interrupted_session_is_reopened_from_the_console(tmp_path: Path) -> None:
    rs = start_server(tmp_path, time_limit_s=60.0, training_runs=1)
    srv = rs.server
    code = srv.enrol("P01")
    assert srv.summaries()[0].elapsed_s is None  # not started: no session time yet
    srv.act(code, "start")
    live = srv.session(code)
    live.agree()
    assert wait_until(lambda: srv.summaries()[0].elapsed_s is not None, timeout=5)
    live.start_trial()
    assert wait_until(lambda: live.run is not None and live.run.ticks > 5)
    srv.stop()  # the server goes down mid-run; the store stays
    protocol = rs.protocol
    store = open_store(tmp_path / "study.db", protocol)
    again = StudyServer(
        session_factory(store, protocol),
        condition_words=protocol.condition_words,
        host="127.0.0.1",
        port=0,
        experimenter_port=0,
    )
    try:
        assert again.reopenable() == ["P01"]
        with pytest.raises(ServerError, match="no interrupted session"):
            again.reopen("P02")
        new_code = again.reopen("P01")
        assert again.reopenable() == []
        live = again.session(new_code)
        assert live.session.phase() == "waiting"  # the experimenter starts it again
        again.act(new_code, "start")
        assert live.session.phase() == "ready"
        # the session clock is read from what the start wrote (another thread under load)
        assert wait_until(lambda: again.summaries()[0].elapsed_s is not None, timeout=5)
        detail = again.detail(new_code)
        assert detail is not None and detail.summary.elapsed_s is not None
        assert "run 1: practice, unassisted -> interrupted" in " ".join(
            r[2] for r in detail.timeline
        )
        assert "session reopened" in [r[2] for r in detail.timeline]
        assert detail.condition == "practice, unassisted, attempt 2"
        assert set(detail.actions) == {"pause", "skip", "withdraw", "end"}
    finally:
        again.stop()
        store.close()


def test_reasons_are_required_and_the_condition_line_fits_the_step(tmp_path: Path) -> None:
    rs = start_server(tmp_path, time_limit_s=1.0, training_runs=1)
    srv = rs.server
    try:
        code = srv.enrol("P01")
        for action in ("end", "withdraw"):
            with pytest.raises(MissingReasonError, match=f"{action} needs a reason"):
                srv.act(code, action, reason="  ")
        assert rs.store.session("P01").status == "enrolled"
        srv.act(code, "start")
        live = srv.session(code)
        live.agree()
        live.start_trial()
        assert wait_until(lambda: live.session.phase() == "questions", timeout=30)
        _answer(live)
        live.start_trial()
        assert wait_until(lambda: live.session.phase() == "questions", timeout=30)
        detail = srv.detail(code)
        assert detail is not None
        assert (
            detail.condition.startswith("questions after: ") and "attempt" not in detail.condition
        )
        assert "redo" in detail.actions
        with pytest.raises(MissingReasonError):
            srv.act(code, "redo")
        assert [t.status for t in rs.store.trials()].count("redone") == 0
        srv.act(code, "redo", reason="the participant asked a question mid-run")
        detail = srv.detail(code)
        assert detail is not None and detail.condition.endswith("first run, attempt 2")
        assert "redo: the participant asked a question mid-run" in [r[2] for r in detail.timeline]
        progress = srv.progress()
        assert (progress.completed, progress.running, progress.stopped) == (0, 1, 0)
        assert progress.planned == rs.protocol.study.participants
        assert progress.conditions == ()  # the one task run was redone: nothing counts
        assert progress.next_row == 1 and len(progress.next_schedule) == 8
        srv.act(code, "end", reason="test over")
        assert srv.detail(code).condition == "none: the session is ended"  # type: ignore[union-attr]
        assert srv.progress().stopped == 1 and srv.detail(code).actions == ()  # type: ignore[union-attr]
    finally:
        rs.stop()


def test_the_plots_never_pair_one_runs_goals_with_anothers_rows() -> None:
    """A run starting while the console reads its plots (the control thread restarting them
    with two goals after a one-goal practice run) gives the console one run's goals and rows,
    never the practice's rows under the task's two goal names (CI: the console refresh failed
    with an IndexError)."""
    plots = LivePlots()
    stop = threading.Event()

    def control() -> None:
        n = 1
        while not stop.is_set():
            n = 3 - n
            plots.restart([f"goal{k}" for k in range(n)])
            for t in range(3):
                plots.add(
                    SimpleNamespace(
                        t=t * 0.01, alpha=0.0, confidence=0.0, probabilities=np.full(n, 1.0 / n)
                    )
                )  # type: ignore[arg-type]

    thread = threading.Thread(target=control)
    thread.start()
    try:
        shapes = []
        for _ in range(20_000):
            names, t, _alpha, _conf, probs = plots.arrays()
            shapes.append((len(names), probs.shape[1], len(t), probs.shape[0]))
    finally:
        stop.set()
        thread.join()
    assert all(a == b and c == d for a, b, c, d in shapes), shapes[:5]
    assert {s[0] for s in shapes} == {1, 2}, "both runs' goals were read"

"""A run that begins while the page thread is still ending the last one keeps running.

The page thread notices a run is over and ends it (stops its ticking, tells the outcome). If the
participant answered the items and pressed Start in between -- the page thread late, as on a
busy machine -- ending "the current run" stopped the new run after a tick or two: its clock
stood at 0.02 s until the experimenter stepped in (seen once in a full test run, 4 workers on
2 cores). Here the page thread is held at exactly that point.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

from study.server.live.live_session import LiveSession
from tests.browser.harness import start_server, wait_until

TIME_LIMIT_S = 1.0


def test_start_pressed_while_the_last_run_is_being_ended_runs_to_its_end(tmp_path: Path) -> None:
    rs = start_server(tmp_path, time_limit_s=TIME_LIMIT_S, training_runs=1)
    srv = rs.server
    try:
        code = srv.enrol("P01")
        srv.act(code, "start")
        live = srv.session(code)
        live.agree()
        live._sync = lambda: None  # type: ignore[method-assign]  # the page thread runs late
        live.start_trial()
        assert wait_until(lambda: live.session.phase() == "questions", timeout=30)
        live.answer({i.id: 4 for i in live.session.screen().items})
        with live._lock:  # the participant's Start holds the lock; the page thread, late, ...
            late = threading.Thread(target=LiveSession._sync, args=(live,))
            late.start()  # ... has seen the practice run over and waits to end it
            time.sleep(0.3)
            live.start_trial()
        late.join(timeout=10)
        del live._sync  # type: ignore[attr-defined]
        assert wait_until(lambda: live.session.phase() == "questions", timeout=30), (
            f"the task run stood still at {live.run.trial.t if live.run else None} s"
        )
        task = [t for t in rs.store.trials() if t.phase == "task"]
        assert [(t.status, t.outcome) for t in task] == [("completed", "timeout")]
        assert task[0].duration_s >= TIME_LIMIT_S - 0.02
    finally:
        rs.stop()

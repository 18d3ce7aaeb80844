"""Held keys are a state the page resends, so a lost release is repaired (issue 22).

In Chromium, a participant holds W for a second and lets go; the server loses the message
that carried the release (the firewall refuses it, as a flood's budget once did). The page
sends its state again 250 ms later, so the arm stops within half a second instead of moving on
(a lost release once left it moving 50-91 mm), and the lost message is an ``input_dropped``
event in the store. A reload then rejoins with the tab's rejoin cookie, without a code.
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import pytest

from study.server import viser_door
from tests.browser.harness import RunningServer, start_server, wait_until
from tests.browser.page import connect_page, join, settle_frames

pytestmark = pytest.mark.browser


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(tmp_path, time_limit_s=90.0, training_runs=1)
    try:
        yield rs
    finally:
        rs.stop()


def _first_run(study: RunningServer, page: Any) -> Any:
    """Enrol P01, join on ``page``, agree and start the practice run; its live session."""
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    live = srv.session(code)
    connect_page(page, study.url)
    join(page, code)
    page.get_by_role("button", name="I have read this and agree to take part").click()
    page.get_by_role("button", name="Start").click()
    assert wait_until(lambda: live.control_loop is not None, timeout=60)
    settle_frames(page)
    return live


def test_a_lost_key_release_is_repaired_by_the_next_state(study: RunningServer, small: Any) -> None:
    srv = study.server
    page = small.new_page()
    live = _first_run(study, page)

    screen = srv.firewall.screen
    keys_uuid = viser_door.element_uuid(
        live.page._keys
    )  # the hidden element the page's key state goes to
    lost: list[str] = []

    def losing_the_first_release(raw: bytes) -> str | None:
        body = msgspec.msgpack.decode(raw)
        value = str(body.get("updates", {}).get("value", "")) if isinstance(body, dict) else ""
        if not lost and body.get("uuid") == keys_uuid and re.fullmatch(r"\d+ ", value):
            lost.append(value)  # nothing held: the release
            return "lost on the way (test)"
        return screen(raw)

    srv.firewall.screen = losing_the_first_release  # type: ignore[method-assign]
    source = live.participant_input
    start = np.array(live.run.trial.user_target)
    page.keyboard.down("w")
    assert wait_until(lambda: source.keyboard.held == frozenset("w"), timeout=5)
    page.wait_for_timeout(1000)
    page.keyboard.up("w")
    released = time.monotonic()
    assert wait_until(lambda: lost, timeout=5), "the release never reached the firewall"
    assert wait_until(lambda: not source.keyboard.moving, timeout=2)
    stopped_after = time.monotonic() - released
    at_stop = np.array(live.run.trial.user_target)
    page.wait_for_timeout(700)
    assert np.allclose(np.array(live.run.trial.user_target), at_stop)  # it stays stopped
    assert 0.05 < float(at_stop[0] - start[0]) < 0.2  # about a second at 0.1 m/s
    assert stopped_after < 0.8, f"stopped {stopped_after:.2f} s after the release"
    srv.firewall.screen = screen  # type: ignore[method-assign]
    assert wait_until(lambda: "input_dropped" in [e.kind for e in study.store.events()], timeout=5)

    page.reload()  # the rejoin cookie: straight back, no code typed
    page.get_by_role("button", name="Continue").wait_for(timeout=60_000)
    assert live.page is not None


STARVED_TIMERS_JS = """() => {
  const every = window.setInterval;
  window.__starved = false;
  window.setInterval = function (fn, ms, ...rest) {
    return every.call(this, function (...a) { if (!window.__starved) return fn.apply(this, a); },
                      ms, ...rest);
  };
}"""
"""Every repeating timer of the page skips its calls while ``window.__starved`` (what a page
busy drawing in software on a loaded machine does to them: late by a second or more)."""


def test_a_held_key_stays_held_while_the_pages_timers_starve(
    study: RunningServer, small: Any
) -> None:
    page = small.new_page()
    page.add_init_script(f"({STARVED_TIMERS_JS})()")
    live = _first_run(study, page)
    source = live.participant_input

    page.evaluate("() => { window.__starved = true; }")
    page.keyboard.down("d")  # held without auto-repeat: only the page's frames resend it
    assert wait_until(lambda: source.keyboard.held == frozenset("d"), timeout=5)
    start = np.array(live.run.trial.user_target)
    held = []
    end = time.monotonic() + 3.0
    while time.monotonic() < end:
        page.wait_for_timeout(100)
        held.append(source.keyboard.held == frozenset("d"))
    moved = abs(float(live.run.trial.user_target[1] - start[1]))
    page.keyboard.up("d")
    page.evaluate("() => { window.__starved = false; }")
    assert wait_until(lambda: not source.keyboard.held, timeout=5)
    kinds = [e.kind for e in study.store.events()]
    print(f"held at {sum(held)} of {len(held)} looks, moved {moved * 100:.1f} cm")
    assert "keys_expired" not in kinds, "the server let go of a key the participant held"
    assert all(held), held
    assert moved > 0.2, f"the target moved {moved:.3f} m in 3 s of D held"  # 0.1 m/s

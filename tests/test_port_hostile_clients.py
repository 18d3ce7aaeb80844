"""The participant port under attack: raw websocket clients that speak viser's protocol.

Each test does what a hostile or careless client on the lab network could do and checks what a
researcher would notice: no share tunnel opens, a huge message costs one connection and no
control ticks, a control-loop error pauses the trial and tells the experimenter instead of
killing the loop, join codes cannot be guessed or used to take over a dropped session, and the
ready screen never shows a previous run's end state.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import pytest
import viser
import websockets

from study.server.firewall import Firewall, FirewallConfig
from study.server.join import ALPHABET, CODE_LENGTH
from study.server.participant_tabs import JOIN_FAILED, JOIN_THROTTLED
from tests import disk_full
from tests.attacker import CAMERA, SUBPROTOCOL
from tests.browser.harness import RunningServer, run_async, start_server, wait_until
from tests.support.raw_client import AGREE, RawClient
from tests.support.served import served_as_serve_runs_it  # noqa: F401 (the modules' fixture)

pytestmark = pytest.mark.usefixtures("served_as_serve_runs_it")


def roomy() -> Firewall:
    """The participant port's rules with a wider accept gate: these tests open many sockets
    from 127.0.0.1 one after another (the gate has its own tests)."""
    return Firewall(
        FirewallConfig(new_tabs_per_s=None, accept_burst=500.0, accept_total_per_s=500.0)
    )


@pytest.fixture
def study(tmp_path: Path) -> Any:
    rs = start_server(
        tmp_path, time_limit_s=30.0, training_runs=1, server_kw={"port_firewall": roomy()}
    )
    try:
        yield rs
    finally:
        ended = rs.stop()
    assert ended, "the server's threads still ran after the stop's wait (a connection held it)"


def _started(rs: RunningServer) -> tuple[Any, str, Any]:
    """The server, the join code and the live session of participant P01, started."""
    code = rs.server.enrol("P01")
    rs.server.act(code, "start")
    return rs.server, code, rs.server.session(code)


def _kinds(rs: RunningServer) -> list[str]:
    return [e.kind for e in rs.store.events()]


def _markdown(c: RawClient) -> list[str]:
    return [
        m["props"]["_markdown"]
        for m in c.messages
        if m.get("type") == "GuiMarkdownMessage" and "props" in m
    ]


async def _shown(c: RawClient, text: str, *, times: int = 1, timeout: float = 10.0) -> None:
    """Wait until ``text`` has been in ``times`` of the tab's markdown messages (a loaded
    machine delivers them late; a fixed sleep once missed the throttle notice)."""
    end = time.monotonic() + timeout
    while sum(text in t for t in _markdown(c)) < times:
        assert time.monotonic() < end, f"{text!r} not shown {times} times in {timeout} s"
        await asyncio.sleep(0.05)


async def _running(c: RawClient, code: str) -> str:
    """Join, agree and start the first run; returns the handle's owner (poses must carry it)."""
    await c.join(code)
    await c.click(AGREE)
    await c.click("Start")
    handle = await c.wait_for(lambda m: m.get("type") == "TransformControlsMessage")
    return str(handle.get("owner", ""))


def _wrong(code: str) -> str:
    """A well-formed code that is not ``code``."""
    return "".join(ALPHABET[(ALPHABET.index(ch) + 1) % len(ALPHABET)] for ch in code)


def test_no_share_tunnel_from_either_port(study: RunningServer) -> None:
    srv = study.server

    async def ask(port: int) -> None:
        async with RawClient(port) as c:
            await c.send("ShareUrlRequest")
            await asyncio.sleep(0.5)

    run_async(ask(srv.participant_port))
    run_async(ask(srv.experimenter_port))
    time.sleep(0.5)
    assert srv.participant._share_tunnel is None
    assert srv.experimenter._share_tunnel is None
    assert srv.firewall.dropped["ShareUrlRequest"] == 1
    assert srv.experimenter_firewall.dropped["ShareUrlRequest"] == 1


def test_a_huge_message_costs_its_connection_not_the_control_loop(study: RunningServer) -> None:
    srv, code, live = _started(study)

    async def attack() -> None:
        async with RawClient(srv.participant_port) as c:
            await _running(c, code)
            assert wait_until(lambda: live.control_loop is not None, timeout=10)
            ticks = live.control_loop.ticks
            t0 = time.monotonic()
            big = msgspec.msgpack.encode(
                {
                    "type": "TransformControlsUpdateMessage",
                    "name": "/handle",
                    "wxyz": [1.0, 0.0, 0.0, 0.0],
                    "position": [0.5, 0.0, 0.3],
                    "owner": "x" * 5_000_000,
                }
            )
            with contextlib.suppress(websockets.ConnectionClosed):
                await c.ws.send(big)
            await asyncio.wait_for(c.ws.wait_closed(), timeout=10)
            await asyncio.sleep(1.0)
            rate = (live.control_loop.ticks - ticks) / (time.monotonic() - t0)
            assert c.ws.close_code == 1009  # "message too big"
        # the loop ran on (it paused when the tab went away, as for any lost tab)
        assert live.control_loop.error is None and rate > 50

    run_async(attack())
    assert wait_until(lambda: live.page is None, timeout=5)
    assert "pause" in _kinds(study)


def test_a_control_fault_pauses_the_trial_and_tells_the_experimenter(
    study: RunningServer,
) -> None:
    srv, code, live = _started(study)

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as c:
            await _running(c, code)
            assert wait_until(lambda: live.control_loop is not None, timeout=10)
            trial = live.run.trial
            real_tick = trial.tick

            def broken() -> Any:
                trial.tick = real_tick  # fails once, like a transient fault
                raise OverflowError("(34, 'Numerical result out of range')")

            trial.tick = broken
            assert wait_until(lambda: live.fault is not None, timeout=5)
            await asyncio.sleep(0.5)
            assert live.run.paused and live.control_loop.alive
            assert any("experimenter will continue" in t for t in _markdown(c))
            detail = srv.detail(code)
            assert detail is not None and "OverflowError" in (detail.fault or "")
            # input during the fault is refused, not queued
            await c.pose((0.55, 0.05, 0.3))
            await asyncio.sleep(0.3)
            srv.act(code, "resume")
            assert wait_until(lambda: live.fault is None and not live.run.paused, timeout=5)
            t = live.run.trial.t
            assert wait_until(lambda: live.run.trial.t > t + 0.5, timeout=5)

    run_async(scenario())
    kinds = _kinds(study)
    assert "control_fault" in kinds and "pause" in kinds and "resume" in kinds
    fault = next(e for e in study.store.events() if e.kind == "control_fault")
    assert "OverflowError" in str(fault.detail)


def test_join_codes_resist_guessing_and_every_failure_reads_the_same(
    study: RunningServer,
) -> None:
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    assert len(code) == CODE_LENGTH and set(code) <= set(ALPHABET)

    async def guesser() -> None:
        async with RawClient(srv.participant_port) as c:
            for k in range(5):
                await c.type_code(_wrong(code) if k else "0000")
                await _shown(c, JOIN_FAILED, times=k + 1)
            await c.type_code(code)  # the right code, but this tab has used up its tries
            await _shown(c, JOIN_THROTTLED)
            assert srv.session(code).page is None

    run_async(guesser())

    async def holder_and_intruder() -> None:
        async with RawClient(srv.participant_port) as a, RawClient(srv.participant_port) as b:
            await a.join(code)
            await b.type_code(code)  # right code while another tab holds the session
            await _shown(b, JOIN_FAILED)
            assert srv.session(code).page.client.client_id != -1
            held_by = srv.session(code).page.client.client_id
            await a.ws.close()
            assert wait_until(lambda: srv.session(code).page is None, timeout=5)
            await asyncio.sleep(0.5)
            # b is still connected but is not bound to the dropped session without its code
            assert srv.session(code).page is None
            await b.type_code(code)
            assert wait_until(lambda: srv.session(code).page is not None, timeout=5)
            assert srv.session(code).page.client.client_id != held_by

    run_async(holder_and_intruder())
    assert "second_tab_refused" in _kinds(study)
    joins = [e for e in study.store.events() if e.kind == "participant_connected"]
    assert len(joins) == 2 and all("address" in str(e.detail) for e in joins)


def test_a_kiosk_binds_its_one_session_without_a_code(tmp_path: Path) -> None:
    rs = start_server(tmp_path, server_kw={"kiosk": True})
    try:
        code = rs.server.enrol("P01")
        rs.server.act(code, "start")

        async def tab() -> None:
            async with RawClient(rs.server.participant_port) as c:
                await c.button(AGREE)
                assert not any(
                    m.get("type") == "GuiTextMessage" and m["props"]["label"] == "Join code"
                    for m in c.messages
                )

        run_async(tab())
    finally:
        rs.stop()


def test_the_ready_screen_shows_the_next_trials_start_never_the_last_end(tmp_path: Path) -> None:
    """After a run that moved the arm, every frame sent while the next run's ready screen
    shows is that run's start state (the render loop used to re-send the old end pose)."""
    rs = start_server(tmp_path, time_limit_s=4.0, training_runs=1)
    srv, code, live = _started(rs)
    sent: list[tuple[str, np.ndarray]] = []

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as c:
            owner = await _running(c, code)
            assert wait_until(lambda: live.scene_view is not None, timeout=10)
            for k in range(20):  # drag the target up and away: the arm ends far from its start
                await c.pose((0.45 + 0.01 * k, 0.1, 0.3 + 0.01 * k), owner=owner)
                await asyncio.sleep(0.05)
            await asyncio.sleep(1.0)
            end = live.run.trial.sim.data.xpos.copy()
            view_render = type(live.scene_view).render

            def spy(view: Any, xpos: np.ndarray, xmat: np.ndarray, **kw: Any) -> None:
                sent.append((live.session.phase(), np.array(xpos)))
                view_render(view, xpos, xmat, **kw)

            type(live.scene_view).render = spy  # type: ignore[method-assign]

            def starts() -> int:
                return sum(
                    m.get("type") == "GuiButtonMessage" and m["props"]["label"] == "Start"
                    for m in c.messages
                )

            shown = starts()  # the first run's Start button is among the messages already
            try:
                await c.button("Continue")  # the practice run timed out: its outcome
                await c.click("Continue")
                items = []
                while len(items) < 3:
                    items = [m for m in c.messages if m.get("type") == "GuiButtonGroupMessage"]
                    await asyncio.sleep(0.1)
                for g in items:
                    await c.send("GuiUpdateMessage", uuid=g["uuid"], updates={"value": "4"})
                await asyncio.sleep(0.3)
                await c.click("Continue")
                await c.wait_for(lambda _m: starts() > shown)  # the next run's ready screen
                await asyncio.sleep(1.5)  # many render-loop periods on the ready screen
            finally:
                type(live.scene_view).render = view_render  # type: ignore[method-assign]
            ready = [x for phase, x in sent if phase == "ready"]
            assert ready, "the ready screen sent no frame of the next scene"
            start = ready[0]
            for xpos in ready:
                assert np.allclose(xpos, start), "a ready-screen frame left the start state"
            n = min(len(start), len(end))  # the arm comes first; the scenes differ in objects
            assert float(np.max(np.abs(start[:n] - end[:n]))) > 0.05  # the old end was far

    try:
        run_async(scenario())
    finally:
        rs.stop()


def test_nan_and_huge_poses_never_reach_the_trial(study: RunningServer) -> None:
    srv, code, live = _started(study)

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as c:
            await _running(c, code)
            assert wait_until(lambda: live.participant_input is not None, timeout=10)
            for position in ((1e200, 0.0, 0.3), (math.nan,) * 3, (11.0, 0.0, 0.3), "abc"):
                await c.pose(position)
            await asyncio.sleep(0.5)
            assert live.control_loop.error is None and live.fault is None
            assert float(np.max(np.abs(live.run.trial.user_target))) < 2.0

    run_async(scenario())
    assert sum(srv.firewall.dropped.values()) >= 4


def test_an_unknown_message_type_is_dropped_and_the_client_keeps_working(
    study: RunningServer,
) -> None:
    srv = study.server
    code = srv.enrol("P01")

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as c:
            for kind in ("FileTransferStartUpload", "GetRenderResponseMessage", "NoSuchThing"):
                await c.send(kind, uuid="x")
            await c.send("ScenePointerMessage", event_type="click")
            await asyncio.sleep(0.3)
            await c.join(code)

    srv.act(code, "start")
    run_async(scenario())
    assert srv.firewall.dropped["FileTransferStartUpload is not accepted here"] == 1
    assert viser.__version__.startswith("1.1.")


def test_a_full_disk_mid_trial_holds_the_trial_and_loses_no_sample(tmp_path: Path) -> None:
    """The store stops taking writes while a participant steers: the trial is held (its clock
    stops), the page asks to wait, the console names the fault; once space is back the
    experimenter resumes and the completed trial has every tick's sample."""
    rs = start_server(tmp_path, time_limit_s=4.0, training_runs=1)
    srv, code, live = _started(rs)

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as c:
            await _running(c, code)
            assert wait_until(lambda: live.run is not None and live.run.trial.t > 0.5)
            disk_full.cap(rs.store, extra_pages=0)
            try:
                assert wait_until(lambda: live.fault is not None, timeout=10)
                held = live.run.trial.t
                await asyncio.sleep(1.0)
                assert live.run.trial.t == pytest.approx(held, abs=0.02)  # the clock stopped
                assert any("experimenter will continue" in t for t in _markdown(c))
                detail = srv.detail(code)
                assert detail is not None and "full" in (detail.fault or "").lower()
            finally:
                disk_full.uncap(rs.store)
            srv.act(code, "resume")
            await c.button("Continue")  # the run went on to its time limit

    try:
        run_async(scenario())
        trial = next(t for t in rs.store.trials() if t.status == "completed")
        assert trial.duration_s == pytest.approx(4.0, abs=0.05)
        assert rs.store.sample_count(trial.trial_id) == trial.ticks
        assert trial.ticks == pytest.approx(400, abs=2)
        faults = [e for e in rs.store.events() if e.kind == "control_fault"]
        assert len(faults) == 1 and "full" in str(faults[0].detail).lower()
    finally:
        rs.stop()


def test_the_door_refuses_other_sites_too_many_sockets_and_oversize_first_messages(
    study: RunningServer,
) -> None:
    """Checks made at the handshake, before viser sees the connection: a page of another site
    (cross-site websocket), a ninth socket from one address, and a huge first message from a
    client that never sent its camera (viser only greets a client after that)."""
    srv = study.server
    sub = [f"viser-v{viser.__version__}"]

    async def attacks() -> None:
        for port in (srv.participant_port, srv.experimenter_port):
            with pytest.raises(websockets.InvalidStatus):
                await websockets.connect(
                    f"ws://127.0.0.1:{port}", subprotocols=sub, origin="http://evil.example"
                )
        same_site = await websockets.connect(
            f"ws://127.0.0.1:{srv.participant_port}",
            subprotocols=sub,
            origin=f"http://127.0.0.1:{srv.participant_port}",
        )
        await same_site.close()
        held = [
            await websockets.connect(f"ws://127.0.0.1:{srv.participant_port}", subprotocols=sub)
            for _ in range(srv.firewall.max_connections_per_address)
        ]
        await asyncio.sleep(0.3)
        with pytest.raises(websockets.InvalidStatus):
            await websockets.connect(f"ws://127.0.0.1:{srv.participant_port}", subprotocols=sub)
        for ws in held:
            await ws.close()
        await asyncio.sleep(0.3)
        quiet = await websockets.connect(f"ws://127.0.0.1:{srv.participant_port}", subprotocols=sub)
        with contextlib.suppress(websockets.ConnectionClosed):
            await quiet.send(b"\x00" * 1_000_000)
        await asyncio.wait_for(quiet.wait_closed(), timeout=10)
        assert quiet.close_code == 1009

    run_async(attacks())
    assert srv.firewall.refused_connections["another site's page"] == 1
    assert srv.experimenter_firewall.refused_connections["another site's page"] == 1
    assert srv.firewall.refused_connections["too many connections from one address"] == 1


def test_a_message_flood_closes_its_connection_and_control_keeps_its_rate(
    study: RunningServer, caplog: pytest.LogCaptureFixture
) -> None:
    srv, code, live = _started(study)

    async def flood() -> None:
        async with RawClient(srv.participant_port) as honest:
            owner = await _running(honest, code)
            assert wait_until(lambda: live.control_loop is not None, timeout=10)
            ticks, t0 = live.control_loop.ticks, time.monotonic()
            async with RawClient(srv.participant_port) as c:
                junk = msgspec.msgpack.encode({"type": "NoSuchThing"})
                with contextlib.suppress(websockets.ConnectionClosed):
                    for _ in range(5000):
                        await c.ws.send(junk)
                # closed by the server; late on a starved machine (10 s once ran out)
                await asyncio.wait_for(c.ws.wait_closed(), timeout=30)
            await asyncio.sleep(1.0)
            rate = (live.control_loop.ticks - ticks) / (time.monotonic() - t0)
            assert rate > 50 and not honest.closed  # 100 Hz setting; one process runs both sides
            await honest.pose((0.5, 0.05, 0.3), owner=owner)
            assert wait_until(
                lambda: abs(float(live.run.trial.user_target[1]) - 0.05) < 1e-9, timeout=5
            )

    with caplog.at_level(logging.INFO):
        run_async(flood())
    assert srv.firewall.closed_connections >= 1
    assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]


def test_condition_words_typed_into_the_page_are_blocked_without_flooding(
    study: RunningServer, caplog: pytest.LogCaptureFixture
) -> None:
    """viser queues an echo of what a tab types on that tab's own connection, which never
    sends it: the guard drops such echoes unread -- a participant's text is data, not a leak,
    and stays out of the log -- and nothing with the words reaches the page."""
    srv = study.server

    async def typist() -> None:
        async with RawClient(srv.participant_port) as c:
            text = await c.wait_for(
                lambda m: m.get("type") == "GuiTextMessage" and m["props"]["label"] == "Join code"
            )
            for k in range(150):
                await c.send("GuiUpdateMessage", uuid=text["uuid"], updates={"value": f"right{k}"})
            await asyncio.sleep(1.0)
            assert not any("right" in str(m).lower() for m in c.messages)

    with caplog.at_level(logging.INFO):
        run_async(typist())
    guard = srv.guard
    assert guard.echoes >= 150 and guard.blocked == 0 and guard.violations == []
    assert not [r for r in caplog.records if "right1" in r.getMessage()]


def test_a_kiosk_does_not_hand_a_dropped_session_to_a_waiting_tab(tmp_path: Path) -> None:
    rs = start_server(tmp_path, server_kw={"kiosk": True})
    srv = rs.server
    try:
        code = srv.enrol("P01")
        srv.act(code, "start")

        async def tabs() -> None:
            async with RawClient(srv.participant_port) as first:
                await first.button(AGREE)
                async with RawClient(srv.participant_port) as waiting:
                    await waiting.wait_for(
                        lambda m: (
                            m.get("type") == "GuiTextMessage" and m["props"]["label"] == "Join code"
                        )
                    )
                    await first.ws.close()
                    assert wait_until(lambda: srv.session(code).page is None, timeout=5)
                    await asyncio.sleep(1.0)
                    assert srv.session(code).page is None  # the waiting tab was not bound
                    await waiting.join(code)  # with the code it is

        run_async(tabs())
    finally:
        rs.stop()


def test_tabs_that_leave_at_once_leave_nothing_behind_and_never_hold_a_session(
    tmp_path: Path,
) -> None:
    """viser runs connect and disconnect callbacks in a pool, in no fixed order; a tab that
    connects and drops at once must not stay registered (on a kiosk it would take the next
    session for good)."""
    rs = start_server(tmp_path, server_kw={"kiosk": True, "port_firewall": roomy()})
    srv = rs.server
    sub = [SUBPROTOCOL]
    camera = CAMERA  # the first message a page sends

    async def hit_and_run() -> None:
        for _ in range(60):
            ws = await websockets.connect(
                f"ws://127.0.0.1:{srv.participant_port}", subprotocols=sub
            )
            await ws.send(camera)
            ws.transport.abort()
        await asyncio.sleep(1.5)

    try:
        run_async(hit_and_run())
        assert wait_until(lambda: not srv.participant.get_clients(), timeout=10)
        time.sleep(0.5)
        assert set(srv.tabs._pages) <= set(srv.participant.get_clients())
        code = srv.enrol("P01")
        time.sleep(0.5)
        assert srv.session(code).page is None  # no dead tab took the kiosk's session
    finally:
        rs.stop()


def test_the_console_answers_only_to_this_machines_names(study: RunningServer) -> None:
    """A page whose own name was made to point at 127.0.0.1 (DNS rebinding) sends a matching
    Origin and Host; the console still refuses it."""
    srv = study.server
    port = srv.experimenter_port

    async def rebound() -> None:
        sock = socket.create_connection(("127.0.0.1", port))
        with pytest.raises(websockets.InvalidStatus):
            await websockets.connect(
                f"ws://evil.example:{port}",
                sock=sock,
                origin=f"http://evil.example:{port}",
                subprotocols=[f"viser-v{viser.__version__}"],
            )
        ok = await websockets.connect(
            f"ws://localhost:{port}", subprotocols=[f"viser-v{viser.__version__}"]
        )
        await ok.close()

    run_async(rebound())
    assert srv.experimenter_firewall.refused_connections["a name other than this machine's"] == 1


FLOOD_SCRIPT = """
import asyncio, sys, time
import msgspec, viser, websockets


port, addresses, per_address, rate, seconds = sys.argv[1:6]
camera = msgspec.msgpack.encode({
    "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [-1.0, 0.0, 1.0],
    "fov": 1.0, "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 800,
    "look_at": [0.45, 0.0, 0.15], "up_direction": [0.0, 0.0, 1.0]})

async def one(address, period, end):
    try:
        async with websockets.connect(
            f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"],
            local_addr=(address, 0), max_queue=4,
        ) as ws:
            nxt = time.monotonic()
            while time.monotonic() < end:
                await ws.send(camera)
                nxt += period
                await asyncio.sleep(max(0.0, nxt - time.monotonic()))
    except Exception:
        pass

async def main():
    end = time.monotonic() + float(seconds)
    period = 1.0 / float(rate)
    await asyncio.gather(*(
        one(f"127.0.0.{2 + a}", period, end)
        for a in range(int(addresses)) for _ in range(int(per_address))))

asyncio.run(main())
"""


def test_many_sockets_under_their_own_rate_cannot_slow_the_control_loop(
    study: RunningServer,
) -> None:
    """56 sockets from 7 addresses, each under the per-connection rate (about 10,000 messages a
    second in all, from another process): none of them holds a session, so they share the
    unbound budget and wait for it (their frames stay in the kernel), and the 100 Hz control
    loop keeps at least half the rate it had before the flood (undefended: 14-37 ticks/s).

    Compared with the rate just before, as the attack tests do: the flooder shares 2 cores with
    the server and with other tests (CI once saw 89 ticks/s against a fixed bound of 90, the
    flooder itself taking a core). Without the unbound budget the loop fell to 14-37 ticks/s;
    ``benchmarks/server.py`` holds the strict figure, with the server in the real-time class."""
    srv, code, live = _started(study)
    seconds = 6.0

    async def session_under_flood() -> tuple[float, float]:
        async with RawClient(srv.participant_port) as honest:
            await _running(honest, code)
            assert wait_until(lambda: live.control_loop is not None, timeout=10)
            ticks, t0 = live.control_loop.ticks, time.monotonic()
            await asyncio.sleep(2.0)
            before = (live.control_loop.ticks - ticks) / (time.monotonic() - t0)
            argv = [str(srv.participant_port), "7", "8", "180", str(seconds)]
            flooder = subprocess.Popen([sys.executable, "-c", FLOOD_SCRIPT, *argv])
            try:
                await asyncio.sleep(2.0)  # the flood is under way
                ticks, t0 = live.control_loop.ticks, time.monotonic()
                await asyncio.sleep(3.0)
                rate = (live.control_loop.ticks - ticks) / (time.monotonic() - t0)
            finally:
                flooder.wait(timeout=30)
            assert not honest.closed
            return before, rate

    before, rate = run_async(session_under_flood())
    print(f"control loop: {before:.1f} ticks/s before the flood, {rate:.1f} under it")
    # undefended the loop fell to 14-37 ticks/s; defended, on a loaded 2-core host beside the
    # other workers' browsers (their GPU threads at nice -8), 60-78 was seen as well as 100
    assert rate >= 0.5 * before and rate >= 0.5 * live.control_loop.rate_hz
    assert srv.firewall.shares is not None and srv.firewall.shares.delayed > 1000


def test_a_text_frame_closes_its_connection_without_a_traceback(
    study: RunningServer, caplog: pytest.LogCaptureFixture
) -> None:
    srv = study.server

    async def texts() -> list[int | None]:
        codes = []
        for _ in range(20):
            async with RawClient(srv.participant_port) as c:
                with contextlib.suppress(websockets.ConnectionClosed):
                    await c.ws.send("hello")
                await asyncio.wait_for(c.ws.wait_closed(), timeout=10)
                codes.append(c.ws.close_code)
        return codes

    with caplog.at_level(logging.INFO):
        codes = run_async(texts())
    assert codes == [1003] * 20  # "unsupported data", closed by the server
    assert srv.firewall.dropped["text frame"] == 20
    assert not [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]
    # one line per reason (refused, closed), and one "connection open" line, not 20
    assert sum("text frame" in r.getMessage() for r in caplog.records) == 2
    assert sum(r.getMessage() == "connection open" for r in caplog.records) <= 1


def _handshake(port: int, host: str, extra: str = "") -> int:
    """The HTTP status a websocket handshake with these headers gets."""
    request = (
        f"GET / HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
        f"Sec-WebSocket-Protocol: viser-v{viser.__version__}\r\n{extra}\r\n"
    )
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        sock.sendall(request.encode())
        return int(sock.recv(4096).split(b" ")[1])


def test_repeated_headers_and_host_tricks_are_forbidden(study: RunningServer) -> None:
    srv = study.server
    part, console = srv.participant_port, srv.experimenter_port
    assert _handshake(console, f"localhost:{console}") == 101
    assert _handshake(part, f"127.0.0.1:{part}") == 101
    for port in (part, console):
        assert _handshake(port, f"localhost:{port}", f"Host: evil.example:{port}\r\n") == 403
        assert _handshake(port, f"localhost:{port}", "Upgrade: websocket\r\n") == 403
        origin = f"Origin: http://localhost:{port}\r\n"
        assert _handshake(port, f"localhost:{port}", origin * 2) == 403
    # names that urlsplit reads as localhost, but that a browser sends for another site
    assert _handshake(console, f"evil.example@localhost:{console}") == 403
    assert _handshake(console, f"localhost/.evil.example:{console}") == 403
    assert _handshake(part, f"evil.example@127.0.0.1:{part}") == 403
    assert srv.experimenter_firewall.refused_connections["a repeated Host header"] == 1
    assert srv.experimenter_firewall.refused_connections["a malformed Host header"] == 2


def test_frames_below_a_message_are_bounded_and_the_honest_tab_goes_on(
    study: RunningServer,
) -> None:
    """A message that never ends (empty fragments, which the websocket library would keep
    without limit) is closed after 64 frames, and a ping flood (each ping answered) after its
    burst; the honest participant's pose still lands and their session is not paused."""
    srv, code, live = _started(study)

    async def endless() -> Any:
        n = 0
        while True:
            yield b""
            n += 1
            if n % 50 == 0:
                await asyncio.sleep(0)

    async def attack() -> tuple[int | None, int | None, int]:
        async with RawClient(srv.participant_port) as honest:
            owner = await _running(honest, code)
            assert wait_until(lambda: live.control_loop is not None, timeout=10)
            async with RawClient(srv.participant_port) as c:
                with contextlib.suppress(websockets.ConnectionClosed):
                    await asyncio.wait_for(c.ws.send(endless()), timeout=10)
                await asyncio.wait_for(c.ws.wait_closed(), timeout=10)
                fragments = c.ws.close_code
            async with RawClient(srv.participant_port) as c:
                pings = 0
                with contextlib.suppress(websockets.ConnectionClosed):
                    for pings in range(1, 2001):
                        await c.ws.ping()
                        if pings % 20 == 0:
                            await asyncio.sleep(0.01)
                await asyncio.wait_for(c.ws.wait_closed(), timeout=10)
                pinged = c.ws.close_code
            await honest.pose((0.5, -0.04, 0.3), owner=owner)
            assert wait_until(
                lambda: abs(float(live.run.trial.user_target[1]) + 0.04) < 1e-9, timeout=5
            )
            assert not honest.closed
            # asked while the honest tab is still open: leaving the block closes it, which
            # pauses the run (a tab lost), sooner or later as the machine is loaded
            assert not live.session.paused
            return fragments, pinged, pings

    fragments, pinged, pings = run_async(attack())
    assert fragments == 1009, fragments  # message too big: closed, nothing more kept
    # closed once past its burst of 20; the client sends 20 pings every 10 ms until the close
    # reaches it, which a loaded server's loop sends a few hundred ms late (201 seen)
    assert pinged == 1008 and pings < 600, (pinged, pings)
    assert srv.firewall.closed_connections >= 2


def test_a_flood_that_hangs_up_while_held_back_frees_its_slots_at_once(
    study: RunningServer,
) -> None:
    """Eight sockets from one address each push 500 camera messages (far past their share,
    so their reads are held back with hundreds of frames queued) and hang up. The server's reads
    of them are paused, so asyncio never hears of the hang-up: their slots stayed for the whole
    queue, its frames handed to viser at the share's pace for 20-30 s after the flooder was
    gone. The kernel's view of a held connection is looked at now: the slots go within seconds
    and nothing more of theirs reaches viser."""
    srv = study.server
    fw = srv.firewall

    async def flood_and_hang_up() -> int:
        sockets = []
        for _ in range(8):
            ws = await websockets.connect(
                f"ws://127.0.0.1:{srv.participant_port}",
                subprotocols=[SUBPROTOCOL],
                local_addr=("127.0.0.2", 0),
                ping_interval=None,
            )
            sockets.append(ws)
        for ws in sockets:
            for _ in range(500):
                await ws.send(CAMERA)
        await asyncio.sleep(1.0)  # what they sent is at the server (about 130 KiB each)
        held = sum(s.held for s in fw.slots)
        for ws in sockets:
            ws.transport.abort()  # the socket closed: what the kernel holds, then a FIN
        return held

    held = run_async(flood_and_hang_up())
    assert held >= 4, f"the flood was not held back ({held} held)"
    assert wait_until(lambda: len(fw.slots) == 0, timeout=5), (
        f"{len(fw.slots)} slots of a flooder that hung up are still held"
    )
    passed = fw.passed
    time.sleep(1.0)
    assert fw.passed == passed, "frames of connections that were gone still reached viser"

"""An honest participant under each attack the port has seen: their inputs land, their session
never pauses, and the attack costs what it sends (issue 22).

Each test starts a running trial bound to an honest tab on 127.0.0.1, then runs one attack from
another process (``tests/attacker.py``) from 127.0.0.2 onwards, and meanwhile checks what the
participant would notice: a handle pose lands within two seconds, a key held for half a second
moves the arm and its release stops it (a lost release once left the arm moving 50-91 mm), the
tab stays connected and the session is never paused, and no input of theirs is dropped. The
attacks are the first pass's failures: 40 addresses each far under its own rate, 7 addresses x 8
sockets x 190 messages a second, a reconnect storm, 64 idle sockets, join-code guessers from 6
addresses, and handshakes of another viser version with a 7 KB subprotocol (the log).
"""

from __future__ import annotations

import asyncio
import json
import logging
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import viser
import websockets

from study.server import viser_door
from study.server.firewall import Firewall, FirewallConfig
from study.server.live.live_run import KEY_STATE_MAX_AGE_S
from study.server.page_script import KEY_RESEND_MS
from study.server.participant_page import DEAF_LIMIT_S
from tests.attacker import CAMERA
from tests.browser.harness import RunningServer, run_async, start_server
from tests.support.raw_client import AGREE, RawClient
from tests.support.served import served_as_serve_runs_it  # noqa: F401 (the modules' fixture)

pytestmark = pytest.mark.usefixtures("served_as_serve_runs_it")


ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def study(tmp_path: Path) -> Iterator[RunningServer]:
    rs = start_server(tmp_path, time_limit_s=120.0, training_runs=1)
    try:
        yield rs
    finally:
        ended = rs.stop()
    assert ended, "the server's threads still ran after the stop's wait (a connection held it)"


class Attack:
    """``tests/attacker.py KIND`` in its own process, for ``seconds``."""

    def __init__(self, kind: str, port: int, *, seconds: float, **options: float) -> None:
        argv = [sys.executable, "-m", "tests.attacker", kind, "--port", str(port)]
        argv += ["--seconds", str(seconds)]
        for key, value in options.items():
            argv += [f"--{key}", str(value)]
        self.process = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, text=True)

    def result(self) -> dict[str, Any]:
        out, _ = self.process.communicate(timeout=120)
        return json.loads(out.strip().splitlines()[-1])

    def stop(self) -> dict[str, Any]:
        """End it now (the test has seen what it needs under it); what it managed."""
        self.process.terminate()  # the attacker reports on SIGTERM
        return self.result()


class Honest:
    """The participant's tab: joined, consented, trial started; sends what a page sends."""

    def __init__(self, client: RawClient, live: Any) -> None:
        self.c, self.live = client, live
        self.owner = ""
        self.keys_uuid = ""
        self.seq = 0
        self.landed: list[float] = []
        self.silent_s = 0.0
        """The longest this tab itself went without resending a held key's state."""
        self._held_since: float | None = None

    async def start(self, code: str) -> None:
        await self.c.join(code)
        await self.c.click(AGREE)
        await self.c.click("Start")
        handle = await self.c.wait_for(lambda m: m.get("type") == "TransformControlsMessage")
        self.owner = str(handle.get("owner", ""))
        keys = await self.c.wait_for(
            lambda m: m.get("type") == "GuiTextMessage" and m["props"]["label"] == "keys"
        )
        self.keys_uuid = keys["uuid"]
        assert await until(lambda: self.live.control_loop is not None)

    async def keys(self, held: str) -> None:
        self.seq += 1
        now = time.monotonic()
        if self._held_since is not None:
            self.silent_s = max(self.silent_s, now - self._held_since)
        self._held_since = now if held else None
        await self.c.send(
            "GuiUpdateMessage", uuid=self.keys_uuid, updates={"value": f"{self.seq} {held}"}
        )

    async def comes_to_rest(self, trial: Any, *, timeout: float = 2.0) -> bool:
        """Whether the user's target stops moving within ``timeout``: unchanged over 3 ticks."""
        loop = self.live.control_loop
        end = time.monotonic() + timeout
        ticks, seen = loop.ticks, np.array(trial.user_target)
        while time.monotonic() < end:
            await asyncio.sleep(0.02)
            if loop.ticks >= ticks + 3:
                now = np.array(trial.user_target)
                if np.array_equal(now, seen):
                    return True
                ticks, seen = loop.ticks, now
        return False

    async def inputs_land(self) -> None:
        """A pose lands; W held half a second moves the target; its release stops it."""
        y = 0.05 + 0.01 * len(self.landed)
        sent = time.monotonic()
        await self.c.pose((0.5, y, 0.3), owner=self.owner)
        trial = self.live.run.trial
        assert await until(lambda: abs(float(trial.user_target[1]) - y) < 1e-6, timeout=2.0)
        self.landed.append(time.monotonic() - sent)
        source = self.live.participant_input
        before = np.array(trial.user_target)
        await self.keys("w")
        assert await until(lambda: source.keyboard.held == frozenset("w"), timeout=2.0)
        for _ in range(2):  # held, the page resends its key state every KEY_RESEND_MS
            await asyncio.sleep(KEY_RESEND_MS / 1000)
            await self.keys("w")
        await self.keys("")
        assert await until(lambda: not source.keyboard.moving, timeout=2.0), "release lost"
        # ticks begun while W was held may still be writing their steps (a starved loop catches
        # up in a burst): the target comes to rest within a few ticks, then stays
        assert await self.comes_to_rest(trial), "still moving after the release"
        moved = float(np.linalg.norm(np.array(trial.user_target) - before))
        await asyncio.sleep(0.3)
        after = float(np.linalg.norm(np.array(trial.user_target) - before))
        assert moved > 0.005 and after - moved < 1e-9  # moved while held, not after

    def untouched(self, rs: RunningServer) -> None:
        """Still bound, never paused, nothing of theirs dropped. Held keys are let go when
        their state stops arriving for ``KEY_STATE_MAX_AGE_S`` (the server's promise to a
        stalled tab): allowed only if this tab itself, a thread of the server's own process on
        a loaded machine, went that long without resending (CI once: the asyncio loop starved
        while 40 addresses flooded), never when it resent on time."""
        assert not self.c.closed and self.live.page is not None
        assert not self.live.session.paused
        kinds = [e.kind for e in rs.store.events()]
        assert "pause" not in kinds and "input_dropped" not in kinds
        if "keys_expired" in kinds:
            assert self.silent_s >= KEY_STATE_MAX_AGE_S - 0.05, (
                f"keys expired though the tab resent every {self.silent_s:.2f} s at most"
            )


async def until(predicate: Any, *, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        await asyncio.sleep(0.02)
    return bool(predicate())


def under_attack(rs: RunningServer, kind: str, *, seconds: float = 5.0, **options: float) -> Any:
    """An honest session while ``kind`` runs: its inputs land, before, during and after it;
    the control loop keeps at least half the rate it had just before the attack (a loop the
    port's work stalls; ``benchmarks/server.py`` holds the strict figure). Not 75 %: on 2
    cores beside the suite's other workers and Chromium the loop has run at 63-73 % of its
    rate before while the defences held (the flood's shares delayed thousands of messages),
    and with the shares off these floods cost an idle machine's loop 0-10 % (2026-12-04):
    what tells a defended port from an undefended one here is whether the honest inputs land.
    Returns the attack's own report."""
    srv = rs.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    live = srv.session(code)

    async def scenario() -> tuple[dict[str, Any], float]:
        async with RawClient(srv.participant_port) as client:
            honest = Honest(client, live)
            await honest.start(code)
            ticks, t0 = live.control_loop.ticks, time.monotonic()
            await honest.inputs_land()
            await asyncio.sleep(max(0.0, 2.0 - (time.monotonic() - t0)))
            before = (live.control_loop.ticks - ticks) / (time.monotonic() - t0)
            attack = Attack(kind, srv.participant_port, seconds=seconds, **options)
            await asyncio.sleep(1.5)  # under way
            ticks, t0 = live.control_loop.ticks, time.monotonic()
            while time.monotonic() - t0 < seconds - 2.5:
                await honest.inputs_land()
            rate = (live.control_loop.ticks - ticks) / (time.monotonic() - t0)
            result = await asyncio.get_running_loop().run_in_executor(None, attack.result)
            await honest.inputs_land()  # and after it
            honest.untouched(rs)
            return result, before, rate

    result, before, rate = run_async(scenario())
    print(f"{kind}: {result}; control {before:.1f} ticks/s before, {rate:.1f} during")
    assert rate >= 0.5 * before
    return result


def test_forty_quiet_addresses_never_make_the_honest_tab_the_one_to_go(
    study: RunningServer,
) -> None:
    """40 addresses at 40 messages a second each: the first pass's budget closed the honest
    tab as "the heaviest address" after 5 s. Now nothing is closed or dropped: unbound
    connections wait for their address's share."""
    result = under_attack(study, "flood", addresses=40, tasks=1, rate=40)
    assert result["opened"] >= 30
    assert study.server.firewall.closed_connections == 0


def test_eight_sockets_from_seven_addresses_cannot_drop_a_key_release(
    study: RunningServer,
) -> None:
    under_attack(study, "flood", addresses=7, tasks=8, rate=190)
    # the shares held the flood back (none are delayed with them off): each delayed message
    # blocks its socket, so the count follows how fast the loaded server reads, at most the
    # shares' 400 a second (1,300-1,600 in 5 s on a quiet machine, 996 beside a busy suite)
    assert study.server.firewall.shares.delayed > 300


def test_a_reconnect_storm_is_turned_away_before_it_costs_the_server(
    study: RunningServer,
) -> None:
    result = under_attack(study, "storm", addresses=8, tasks=32)
    fw = study.server.firewall
    assert result["refused"] > result["opened"]  # most never reached viser
    assert result["opened"] <= 8 * (6 + 6 * 0.2) + 8  # the new-tab gate's burst and rate
    assert fw.gate.refused + fw.tab_gate.refused > 0


def test_idle_sockets_cannot_lock_a_new_tab_or_a_reload_out(tmp_path: Path) -> None:
    """Every slot of the port held by 16 addresses (a port of 24 slots here, to fill it fast;
    the default 64 needs at least 11 addresses, the new-tab gate lets each open about 3-6),
    first by sockets that never speak, then by ones that greet and idle: a new tab from
    another address still gets a slot (an idle one makes room), and so does a reload
    presenting its rejoin token."""
    rs = start_server(
        tmp_path,
        time_limit_s=120.0,
        training_runs=1,
        server_kw={"port_firewall": Firewall(FirewallConfig(max_connections=24))},
    )
    srv = rs.server
    code = srv.enrol("P01")
    srv.act(code, "start")

    async def scenario() -> None:
        for kind in ("idle", "lurk"):
            attack = Attack(kind, srv.participant_port, seconds=14.0, addresses=16, tasks=96)
            assert await until(lambda: len(srv.firewall.slots) >= 24, timeout=12.0)
            async with RawClient(srv.participant_port) as newcomer:
                await newcomer.join(code)  # a slot, the join screen, the session
                cookie = next(
                    m["source"]
                    for m in newcomer.messages
                    if m.get("type") == "RunJavascriptMessage" and "study-rejoin" in m["source"]
                )
            token = cookie.split("study-rejoin=")[1].split(";")[0]
            assert await until(lambda: srv.session(code).page is None, timeout=5.0)
            reload = await websockets.connect(
                f"ws://127.0.0.1:{srv.participant_port}",
                subprotocols=[f"viser-v{viser.__version__}"],
                additional_headers={"Cookie": f"study-rejoin={token}"},
            )
            await reload.send(CAMERA)
            assert await until(lambda: srv.session(code).page is not None, timeout=10.0)
            await reload.close()
            assert await until(lambda: srv.session(code).page is None, timeout=5.0)
            assert attack.process.poll() is None, "the attack ended before the reload was seen"
            result = await asyncio.get_running_loop().run_in_executor(None, attack.stop)
            # the port's 24 slots were theirs (above); the newcomer took one of them, which on a
            # loaded machine can go before the attacker has read its handshake (23 seen once)
            assert result["opened"] >= 23

    try:
        run_async(scenario())
        assert srv.firewall.slots.evicted >= 2
    finally:
        ended = rs.stop()
    assert ended, "the server's threads still ran after the stop's wait (a connection held it)"


def test_guessers_from_six_addresses_keep_no_one_out(study: RunningServer) -> None:
    """Fast wrong guesses from 6 addresses spend the server-wide budget; a tab from another
    address still types its code and joins (0 of 14 did before), and a reload with its token
    skips the throttle."""
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")

    async def scenario() -> None:
        attack = Attack("guess", srv.participant_port, seconds=12.0, addresses=6, tasks=12)
        assert await until(lambda: srv.throttle.saturated(), timeout=10.0)
        async with RawClient(srv.participant_port) as honest:
            await honest.join(code)
        assert attack.process.poll() is None, "the guessing ended before the tab joined"
        result = await asyncio.get_running_loop().run_in_executor(None, attack.stop)
        assert result["guesses"] > 60

    run_async(scenario())
    assert srv.session(code).ever_attached


def test_other_versions_and_bare_connections_leave_a_few_log_lines(
    study: RunningServer, caplog: pytest.LogCaptureFixture
) -> None:
    """A 7 KB subprotocol of another viser version once wrote a traceback per handshake (9.9 MB
    of log in 10 s); bare TCP connections one line each. Now: refused at the door, a handful of
    one-line records, no traceback, and viser never echoes its version."""
    srv = study.server
    with caplog.at_level(logging.INFO):
        version = Attack("version", srv.participant_port, seconds=4.0, addresses=2, tasks=8)
        bare = Attack("tcp", srv.participant_port, seconds=4.0, addresses=2, tasks=8)
        sent = version.result()["refused"] + bare.result()["opened"]
    records = caplog.records
    assert sent > 200
    assert len(records) < 20, [r.getMessage()[:80] for r in records]
    assert not [r for r in records if r.exc_info]
    assert not any(viser.__version__ in r.getMessage() for r in records)


def test_no_version_string_reaches_the_participant_port(study: RunningServer) -> None:
    port = study.server.participant_port

    async def fetch() -> tuple[bytes, int]:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        await writer.drain()
        head = await reader.readuntil(b"\r\n\r\n")
        writer.close()
        with pytest.raises(websockets.InvalidStatus) as refused:
            await websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=["viser-v0.0.1"])
        return head, refused.value.response.status_code

    head, status = run_async(fetch())
    assert b"200" in head.split(b"\r\n")[0]
    assert b"Server:" not in head and b"websockets" not in head and b"Python" not in head
    assert status == 403  # another version is refused at the door, never with viser's reason


def test_held_keys_are_a_state_resent_and_let_go_when_it_stops(study: RunningServer) -> None:
    """The page resends its key state every 250 ms while a key is held: resent, the key stays
    held; when the state stops arriving (a stalled connection) the key is let go within about
    a second, recorded, and pressed again by the next state that holds it. A message the
    firewall refuses from the bound tab is an ``input_dropped`` event."""
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    live = srv.session(code)

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as client:
            honest = Honest(client, live)
            await honest.start(code)
            source = live.participant_input
            for _ in range(8):  # two seconds of resends: held throughout
                await honest.keys("w")
                stalled = time.monotonic()  # (the last state sent)
                await asyncio.sleep(0.25)
                assert source.keyboard.held == frozenset("w")
            assert await until(lambda: not source.keyboard.moving, timeout=DEAF_LIMIT_S + 1)
            gone = time.monotonic()
            # silence counts while the server listened: on a starved host its loop falls behind
            # (``deaf_until``) and the key waits that long more, never past DEAF_LIMIT_S
            listened_from = max(stalled, live.page.listening.deaf_until)
            assert 0.9 < gone - stalled < DEAF_LIMIT_S + 0.5
            assert gone - listened_from < 2.0
            await honest.keys("w")
            assert await until(lambda: source.keyboard.held == frozenset("w"), timeout=2.0)
            await honest.keys("")
            await client.pose((10.0, 10.0, 10.0), owner=honest.owner)  # refused by the firewall
            assert await until(
                lambda: "input_dropped" in [e.kind for e in study.store.events()], timeout=5.0
            )

    run_async(scenario())
    events = {e.kind: e for e in study.store.events()}
    assert events["keys_expired"].detail == {"keys": "w"}
    assert "handle position" in str(events["input_dropped"].detail)


def test_held_keys_stay_while_the_server_is_behind_and_go_when_it_stays_deaf(
    study: RunningServer,
) -> None:
    """A tab that resends its held key on time keeps it while the server's event loop is behind
    (seen under a 40-address flood on a loaded machine: the resent states waited in the
    server's backlog and the key was let go under the honest participant); a tab that stops
    resending loses it ``DEAF_LIMIT_S`` after its last state even if the loop stays behind."""
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")
    live = srv.session(code)
    loop = viser_door.event_loop(srv.participant)

    async def scenario() -> float:
        async with RawClient(srv.participant_port) as client:
            honest = Honest(client, live)
            await honest.start(code)
            source = live.participant_input
            await honest.keys("w")
            assert await until(lambda: source.keyboard.held == frozenset("w"), timeout=2.0)
            loop.call_soon_threadsafe(time.sleep, 1.6)  # the port's loop behind for 1.6 s
            for _ in range(10):  # 2.5 s of resends on time, the first 1.6 s into the backlog
                await asyncio.sleep(KEY_RESEND_MS / 1000)
                await honest.keys("w")
                assert source.keyboard.held == frozenset("w"), "let go while resent on time"
            stalled = time.monotonic()  # the last state sent; then silence, the loop behind
            await asyncio.sleep(0.2)
            loop.call_soon_threadsafe(time.sleep, DEAF_LIMIT_S + 1.5)
            assert await until(lambda: not source.keyboard.moving, timeout=DEAF_LIMIT_S + 2)
            gone_after = time.monotonic() - stalled

            # read while the tab is still there: its leaving pauses the run (tab_lost)
            def kinds() -> list[str]:
                return [e.kind for e in study.store.events()]

            assert await until(lambda: "keys_expired" in kinds(), timeout=2.0)
            assert kinds().count("keys_expired") == 1 and "pause" not in kinds()
            return gone_after

    gone_after = run_async(scenario())
    # the cap counts from the last state the server heard: the last sent, or on a loaded host
    # one or two resends (0.25 s each) before it, when the last waited in the blocked backlog
    # (2.67 s seen); without the cap the key stays until the block ends (4.7 s), without the
    # listening clock it goes after 1 s
    assert DEAF_LIMIT_S - 0.6 < gone_after < DEAF_LIMIT_S + 0.7


# -- the second pass's attacks on the merged whole (open link, rejoin cookie, text floods) ----
def _cookie(client: RawClient) -> str:
    script = next(
        m["source"]
        for m in client.messages
        if m.get("type") == "RunJavascriptMessage" and "study-rejoin=" in m["source"]
    )
    return script.split("study-rejoin=")[1].split(";")[0]


def test_a_link_tab_gets_no_join_screen_before_its_url_is_read_and_one_session(
    tmp_path: Path,
) -> None:
    """A tab that delays its URL's answer once got the join screen from any other tab's
    coming and going, typed a code, then answered a recruitment ID: bound to two sessions, it
    left the first held by a gone tab (its participant was refused for good)."""
    rs = start_server(tmp_path, time_limit_s=120.0, training_runs=1, server_kw={"open_link": 2})
    srv = rs.server
    code = srv.enrol("P01")
    srv.act(code, "start")

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as tab:
            link = await tab.wait_for(
                lambda m: m.get("type") == "GuiTextMessage" and m["props"]["label"] == "link"
            )
            async with RawClient(srv.participant_port):  # a tab that comes and goes
                await asyncio.sleep(0.5)
            await asyncio.sleep(1.0)
            assert not any(m.get("props", {}).get("label") == "Join code" for m in tab.messages)
            for value in ("P=" + "b" * 24, "."):
                await tab.send("GuiUpdateMessage", uuid=link["uuid"], updates={"value": value})
            await tab.button(AGREE)
            page = next(iter(srv.tabs._pages.values()))
            assert not srv.tabs.bind(page, srv.session(code))  # one tab, one session

    try:
        run_async(scenario())
        assert srv.session(code).page is None
        assert [s.participant for s in srv.sessions() if s.ever_attached] == ["L0001"]
    finally:
        rs.stop()


def test_a_second_tab_of_the_same_browser_leaves_the_rejoin_cookie_alone(
    study: RunningServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A second tab sends the same cookie; refused because the first holds the session, it
    once cleared the cookie the browser shares, so the first tab's next reload met the join
    screen. Now the cookie is cleared only when its session is over."""
    import study.server.participant_tabs as tabs_module

    monkeypatch.setattr(tabs_module, "REJOIN_WAIT_S", 1.0)
    srv = study.server
    code = srv.enrol("P01")
    srv.act(code, "start")

    async def scenario() -> None:
        async with RawClient(srv.participant_port) as first:
            await first.join(code)
            token = _cookie(first)
            cookie = {"Cookie": f"study-rejoin={token}"}
            async with RawClient(srv.participant_port, headers=cookie) as second:
                await second.wait_for(lambda m: m.get("props", {}).get("label") == "Join code")
                await asyncio.sleep(2.0)  # past the wait for the first tab to let go
                cleared = [m for m in second.messages if "study-rejoin=;" in str(m)]
                assert not cleared and srv.session(code).page is not None

    run_async(scenario())


def test_long_texts_cost_what_a_page_sends_and_only_their_own_tab_waits(
    study: RunningServer,
) -> None:
    """8,000 characters 190 times a second from a session's own tab (1.5 MB/s) once took the
    other session's control loop to 0-16 ticks in a 0.25-s window: the server now reads a
    bound tab at most 128 KiB/s after a 1 MiB burst (a person typing sends a tenth of that),
    the other participant's inputs land, and a tab without a session sends no long text."""
    srv = study.server
    codes = [srv.enrol(p) for p in ("P01", "P02")]
    for code in codes:
        srv.act(code, "start")
    live = srv.session(codes[0])
    fw = srv.firewall

    async def flood(client: RawClient, uuid: str, seconds: float) -> int:
        sent, end = 0, time.monotonic() + seconds
        while time.monotonic() < end:
            value = f"{sent} w " + "x" * 7990
            await client.send("GuiUpdateMessage", uuid=uuid, updates={"value": value})
            sent += 1
            await asyncio.sleep(1 / 190)
        return sent

    async def scenario() -> tuple[int, int, float]:
        async with RawClient(srv.participant_port) as a, RawClient(srv.participant_port) as b:
            honest, hostile = Honest(a, live), Honest(b, srv.session(codes[1]))
            await honest.start(codes[0])
            await hostile.start(codes[1])
            passed, honest_sent, start = fw.passed, honest.seq, time.monotonic()
            attack = asyncio.create_task(flood(b, hostile.keys_uuid, 5.0))
            await asyncio.sleep(1.0)
            while not attack.done():
                await honest.inputs_land()
            # the flood's reads: all reads less the honest tab's (its key states and poses)
            honest_sent = honest.seq - honest_sent + len(honest.landed)
            read = fw.passed - passed - honest_sent
            budget = (2**20 + 128 * 2**10 * (time.monotonic() - start)) / 8000
            assert not a.closed and live.page is not None and not live.session.paused
            async with RawClient(srv.participant_port) as c:  # no session: short texts only
                field = await c.wait_for(lambda m: m.get("props", {}).get("label") == "Join code")
                await c.send("GuiUpdateMessage", uuid=field["uuid"], updates={"value": "x" * 65})
                assert await until(lambda: fw.dropped["GuiUpdateMessage"] >= 1)
            return await attack, read, budget

    sent, read, budget = run_async(scenario())
    print(f"sent {sent}, read {read} (budget {budget:.0f}) while it lasted, {fw.slowed} waited")
    assert fw.slowed > 0 and read < budget + 20, (sent, read, budget)  # 5 s: about 210
    assert not [e for e in study.store.events(participant="P01") if e.kind == "input_dropped"]


def test_a_cookie_at_the_door_never_waits_for_an_enrolment(study: RunningServer) -> None:
    """The door asked the server's lock whether a rejoin cookie was good; the lock is held while
    a session is built (7-300 ms here, each link bot's enrolment), so every handshake with any
    cookie, and with it the whole event loop, waited."""
    srv = study.server
    held = threading.Event()

    def enrolment() -> None:
        with srv._lock:
            held.set()
            time.sleep(1.5)

    async def handshake() -> float:
        t = time.monotonic()
        async with RawClient(srv.participant_port, headers={"Cookie": "study-rejoin=forged"}):
            return time.monotonic() - t

    threading.Thread(target=enrolment, daemon=True).start()
    assert held.wait(5.0)
    assert run_async(handshake()) < 1.0

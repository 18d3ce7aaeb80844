"""The study server's process layout: who listens where, join codes, the serve command."""

from __future__ import annotations

import asyncio
import os
import resource
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from study.protocol.blinding import find_words
from study.server.join import (
    ALPHABET,
    CODE_LENGTH,
    JoinThrottle,
    new_join_code,
    new_token,
    normalize_code,
)
from study.server.participant_page import DECLINE
from tests.browser.harness import iter_strings, run_async, start_server, wait_until
from tests.protocol_copies import PAPER_PROTOCOL
from tests.support.raw_client import AGREE, RawClient


def _lan_ip() -> str | None:
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("10.255.255.255", 1))
            ip = str(s.getsockname()[0])
    except OSError:
        return None
    return None if ip.startswith("127.") else ip


def test_experimenter_view_listens_on_loopback_only(tmp_path: Path) -> None:
    rs = start_server(tmp_path, host="0.0.0.0")
    try:
        srv = rs.server
        assert srv.experimenter.get_host() == "127.0.0.1"
        assert srv.participant.get_host() == "0.0.0.0"
        ip = _lan_ip()
        if ip is not None:  # from the LAN: participant port open, experimenter port closed
            with socket.create_connection((ip, srv.participant_port), timeout=2):
                pass
            with pytest.raises(OSError):
                socket.create_connection((ip, srv.experimenter_port), timeout=2).close()
        participant_url, experimenter_url = srv.urls()
        assert participant_url.endswith(f":{srv.participant_port}")
        assert experimenter_url == f"http://127.0.0.1:{srv.experimenter_port}"
    finally:
        rs.stop()


def test_participant_socket_carries_nothing_of_the_console(tmp_path: Path) -> None:
    """A tab on the participant port gets the participant page only: no console, no
    condition, even while the console shows them for a running session."""
    rs = start_server(tmp_path)
    srv = rs.server
    try:
        code = srv.enrol("P01")
        srv.act(code, "start")
        srv.console.select(code)
        assert "easy" in srv.console.schedule_md.content  # the console does show conditions

        async def run() -> list[str]:
            async with RawClient(srv.participant_port) as c:
                await c.join(code)
                await asyncio.sleep(0.5)
                return [s for m in c.messages for s in iter_strings(m)]

        strings = run_async(run())
        assert any("agree" in s for s in strings)
        strings = [s for s in strings if s != code]  # the code the participant typed, echoed
        for marker in ("Experimenter console", "Enrol", "Withdraw", "Arbitration", code):
            assert not any(marker in s for s in strings), marker
        assert not any(find_words(s, rs.protocol.condition_words) for s in strings)
    finally:
        rs.stop()


def test_join_codes_use_an_unambiguous_alphabet_and_are_typed_loosely() -> None:
    taken: set[str] = set()
    for _ in range(500):
        code = new_join_code(taken)
        assert len(code) == CODE_LENGTH and set(code) <= set(ALPHABET) and code not in taken
        taken.add(code)
    assert not set("0O1IL2Z5S8B6G") & set(ALPHABET)
    assert normalize_code(" ac-d e9 ") == "ACDE9"
    assert len(normalize_code("x" * 10_000)) <= 4 * CODE_LENGTH


def test_the_join_throttle_counts_per_tab_and_per_address() -> None:
    throttle = JoinThrottle(per_client=3, per_address=5, window_s=60.0)
    assert [throttle.allow(client=1, address="10.0.0.9") for _ in range(4)] == [True] * 3 + [False]
    assert throttle.allow(client=2, address="10.0.0.9")  # a new tab from the same machine ...
    assert throttle.allow(client=2, address="10.0.0.9")
    assert not throttle.allow(client=3, address="10.0.0.9")  # ... until the address is spent
    assert throttle.allow(client=4, address="10.0.0.10")


def test_a_spent_server_budget_still_lets_a_new_address_try() -> None:
    """Guessers from six addresses spend the server-wide budget; an address that has not been
    trying gets its first tries anyway, so the guessers keep nobody else out."""
    throttle = JoinThrottle(per_client=5, per_address=20, per_server=60, fresh_tries=3)
    for k in range(6):
        for client in range(4 * k, 4 * k + 4):
            while throttle.allow(client=client, address=f"10.0.0.{k}"):
                pass
    assert throttle.saturated()
    assert not throttle.allow(client=99, address="10.0.0.1")  # a guesser's address: no
    assert [throttle.allow(client=100, address="10.0.0.50") for _ in range(4)] == [True] * 3 + [
        False
    ]


def test_join_codes_and_rejoin_tokens_never_carry_a_blinded_word() -> None:
    words = ("hard", "easy", "right", "wrong", "timid", "aggressive")
    for _ in range(2000):
        for text in (new_join_code(avoid=words), new_token(avoid=words)):
            assert not any(w in text.lower() for w in words)
    assert len(new_token()) == 20 and set(new_token()) <= set(ALPHABET)


def test_several_sessions_ask_for_the_code_and_a_wrong_code_is_refused(tmp_path: Path) -> None:
    rs = start_server(tmp_path)
    srv = rs.server
    try:
        codes = [srv.enrol(p) for p in ("P01", "P02")]
        for code in codes:
            srv.act(code, "start")

        async def run() -> None:
            async with RawClient(srv.participant_port) as c:
                await c.type_code("0000")
                await asyncio.sleep(0.5)
                await c.join(codes[1].lower())
                assert srv.session(codes[1]).page is not None
                assert srv.session(codes[0]).page is None

        run_async(run())
        assert wait_until(lambda: srv.session(codes[1]).page is None)  # tab gone -> unbound
    finally:
        rs.stop()


def _usual_open_files_limit() -> None:
    """The soft limit most systems start a process with (1024), under the hard one."""
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(1024, hard), hard))


def test_serve_command_prints_both_urls_and_stops_cleanly(tmp_path: Path) -> None:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    proc = subprocess.Popen(
        [
            sys.executable, "-m", "study", "serve",
            "--protocol", str(PAPER_PROTOCOL),
            "--db", str(tmp_path / "study.db"),
            "--port", "0", "--experimenter-port", "0",
        ],
        cwd=PAPER_PROTOCOL.parents[1], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=_usual_open_files_limit,
    )  # fmt: skip
    try:
        lines: list[str] = []
        deadline = time.monotonic() + 60
        assert proc.stdout is not None
        while time.monotonic() < deadline and not any("experimenter view" in ln for ln in lines):
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
        text = "".join(lines)
        assert "participant view:  http://" in text, text
        assert "experimenter view: http://127.0.0.1:" in text, text
        assert (tmp_path / "study.db").exists()
        # --realtime's default: the server's threads in the real-time class (said if refused)
        allowed = "the real-time class was not allowed" not in text
        assert os.sched_getscheduler(proc.pid) == (os.SCHED_RR if allowed else os.SCHED_OTHER)
        # started at the usual 1024 open files, it took what it may have: room for connections
        soft, hard = resource.prlimit(proc.pid, resource.RLIMIT_NOFILE)
        assert soft == hard, (soft, hard)
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0


def test_serve_refuses_a_port_in_use_instead_of_moving(tmp_path: Path) -> None:
    """Participants open the URL they were given: a taken port is an error, not another port."""
    import socket

    with socket.socket() as busy:
        busy.bind(("0.0.0.0", 0))
        busy.listen()
        port = busy.getsockname()[1]
        proc = subprocess.run(
            [
                sys.executable, "-m", "study", "serve",
                "--protocol", str(PAPER_PROTOCOL),
                "--db", str(tmp_path / "study.db"),
                "--port", str(port), "--experimenter-port", "0",
            ],
            cwd=PAPER_PROTOCOL.parents[1], capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert proc.returncode == 2
    assert f"participant view on 0.0.0.0:{port}: the port is in use" in proc.stderr
    assert "--port" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "study.db").exists()


def test_a_participant_can_decline_consent_after_one_more_question(tmp_path: Path) -> None:
    rs = start_server(tmp_path)
    srv = rs.server
    try:
        code = srv.enrol("P01")
        srv.act(code, "start")

        async def run() -> None:
            async with RawClient(srv.participant_port) as c:
                await c.join(code)
                await c.click(DECLINE)
                await c.click("Back to the consent text")  # changed their mind: nothing happened
                await c.button(AGREE)
                assert rs.store.session("P01").status == "running"
                await asyncio.sleep(0.5)  # the fresh consent screen's buttons, not the old ones
                await c.click(DECLINE)
                await asyncio.sleep(0.5)
                await c.click("Yes, end the session")
                assert wait_until(lambda: rs.store.session("P01").status == "withdrawn", timeout=5)

        run_async(run())
        reasons = [str(e.detail) for e in rs.store.events() if e.kind == "withdraw"]
        assert any("declined consent" in r for r in reasons)
    finally:
        rs.stop()


def test_the_console_shows_the_ports_refusals_and_the_logs_disk_use(tmp_path: Path) -> None:
    log = tmp_path / "serve.log"
    log.write_bytes(b"x" * 3 * 2**20)
    rs = start_server(tmp_path, server_kw={"log_path": log})
    try:
        rs.server.firewall.refused_connections["too many new tabs from one address"] += 5
        line = rs.server.health()
        assert "0 tab(s)" in line and "5 connection(s) refused or closed" in line
        assert "Log: 3.0 of at most 50 MB" in line and str(log) in line
        rs.server.console.refresh()
        assert rs.server.console.health_md.content == line
    finally:
        rs.stop()

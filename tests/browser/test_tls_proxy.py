"""An online participant behind the README's TLS reverse proxy, over a slow network.

Debian's nginx (``.ci/setup`` installs it) terminates TLS with a certificate this test makes,
configured as the README's deployment section says, in front of a study server started with
``trusted_proxies`` and the open link on. Between Chromium and nginx a delaying TCP relay adds
75 ms each way (150 ms round trip) and connects to nginx from 127.0.0.2, so the address nginx
appends to X-Forwarded-For differs from the proxy's own. The participant opens the link over
https, consents, and steers the arm with a held key; the store records the forwarded address,
and the Origin check accepted the public host name nginx forwards.
"""

from __future__ import annotations

import asyncio
import contextlib
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from study.server.forwarded import trusted_networks
from tests.browser.harness import RunningServer, new_context, start_server, wait_until
from tests.browser.page import AGREE, hold, screenshot

pytestmark = pytest.mark.browser

NGINX = shutil.which("nginx") or "/usr/sbin/nginx"
ONE_WAY_S = 0.075
"""Added delay each way: 150 ms round trip."""
CLIENT = "127.0.0.2"
"""The relay's address as nginx sees it (the participant's, as far as the server knows)."""

SITE = """
# the README's site (deployment section), with this test's ports and certificate
server {{
    listen 127.0.0.1:{port} ssl;
    server_name localhost;
    ssl_certificate {cert};
    ssl_certificate_key {key};

    location / {{
        proxy_pass http://127.0.0.1:{upstream};
        proxy_http_version 1.1;
        proxy_set_header Upgrade $http_upgrade;
        proxy_set_header Connection "upgrade";
        proxy_set_header X-Forwarded-For $proxy_add_x_forwarded_for;
        proxy_set_header X-Forwarded-Host $http_host;
        proxy_set_header X-Forwarded-Proto $scheme;
        proxy_read_timeout 3600s;
        proxy_buffering off;
    }}
}}
"""

MAIN = """
user root;
worker_processes 1;
pid {tmp}/nginx.pid;
error_log {tmp}/error.log warn;
events {{ worker_connections 256; }}
http {{
    access_log {tmp}/access.log;
    client_body_temp_path {tmp}/body;
    proxy_temp_path {tmp}/proxy;
    fastcgi_temp_path {tmp}/fastcgi;
    uwsgi_temp_path {tmp}/uwsgi;
    scgi_temp_path {tmp}/scgi;
{site}
}}
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def behind_proxy(tmp_path: Path) -> Iterator[tuple[RunningServer, int]]:
    assert Path(NGINX).exists(), "nginx is missing: .ci/setup installs it (apt package nginx)"
    rs = start_server(
        tmp_path,
        time_limit_s=60.0,
        training_runs=1,
        server_kw={"open_link": 5, "trusted_proxies": trusted_networks(["127.0.0.1"])},
    )
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
         "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost",
         "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True, timeout=60,
    )  # fmt: skip
    port = _free_port()
    site = SITE.format(port=port, cert=cert, key=key, upstream=rs.server.participant_port)
    conf = tmp_path / "nginx.conf"
    conf.write_text(MAIN.format(tmp=tmp_path, site=site))
    check = subprocess.run([NGINX, "-t", "-c", str(conf)], capture_output=True, text=True)
    assert check.returncode == 0, check.stderr
    nginx = subprocess.Popen([NGINX, "-c", str(conf), "-g", "daemon off;"])
    relay = DelayRelay(target=port, delay_s=ONE_WAY_S, source=CLIENT)
    try:
        assert wait_until(lambda: _listening(port), timeout=10), (
            tmp_path / "error.log"
        ).read_text()
        relay.start()
        yield rs, relay.port
    finally:
        relay.stop()
        nginx.terminate()
        nginx.wait(timeout=10)
        rs.stop()


def _listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


class DelayRelay:
    """A TCP relay on 127.0.0.1 that delivers every chunk ``delay_s`` after it arrived (in
    order, either way), connecting to ``target`` from ``source``."""

    def __init__(self, *, target: int, delay_s: float, source: str) -> None:
        self.target, self.delay_s, self.source = target, delay_s, source
        self.port = 0
        self._loop = asyncio.new_event_loop()
        self._server: asyncio.Server | None = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name="delay-relay", daemon=True)

    def start(self) -> None:
        self._thread.start()
        assert self._ready.wait(10)

    def stop(self) -> None:
        """Close the listener, cancel every relayed connection, stop the loop."""
        done = asyncio.run_coroutine_threadsafe(self._shutdown(), self._loop)
        with contextlib.suppress(Exception):
            done.result(timeout=10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)
        self._loop.close()

    async def _shutdown(self) -> None:
        if self._server is not None:
            self._server.close()
        tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        server = self._loop.run_until_complete(asyncio.start_server(self._client, "127.0.0.1", 0))
        self.port = server.sockets[0].getsockname()[1]
        self._ready.set()
        self._loop.run_forever()

    async def _client(self, reader: Any, writer: Any) -> None:
        try:
            up_r, up_w = await asyncio.open_connection(
                "127.0.0.1", self.target, local_addr=(self.source, 0)
            )
        except OSError:
            writer.close()
            return
        await asyncio.gather(self._pipe(reader, up_w), self._pipe(up_r, writer))

    async def _pipe(self, reader: Any, writer: Any) -> None:
        queue: asyncio.Queue[tuple[float, bytes]] = asyncio.Queue()

        async def deliver() -> None:
            while True:
                due, chunk = await queue.get()
                await asyncio.sleep(max(0.0, due - time.monotonic()))
                if not chunk:
                    break
                writer.write(chunk)
                await writer.drain()
            writer.close()

        sender = asyncio.ensure_future(deliver())
        try:
            while chunk := await reader.read(65536):
                queue.put_nowait((time.monotonic() + self.delay_s, chunk))
        except OSError:
            pass
        queue.put_nowait((time.monotonic() + self.delay_s, b""))
        with contextlib.suppress(OSError):
            await sender


def test_a_participant_behind_the_tls_proxy_at_150_ms(
    behind_proxy: tuple[RunningServer, int], browser: Any, screenshots: Path
) -> None:
    rs, port = behind_proxy
    ctx = new_context(browser, viewport={"width": 1100, "height": 720}, ignore_https_errors=True)
    ctx.set_default_timeout(60_000)
    try:
        page = ctx.new_page()
        t0 = time.monotonic()
        page.goto(f"https://localhost:{port}/?PROLIFIC_PID=5f3c1a2b3c4d5e6f7a8b9c0d")
        page.get_by_role("button", name=AGREE).wait_for()
        print(f"link to consent over TLS at 150 ms: {time.monotonic() - t0:.1f} s")
        connected = [e for e in rs.store.events() if e.kind == "participant_connected"]
        assert [e.detail["address"] for e in connected] == [CLIENT]  # the forwarded hop
        assert rs.server.firewall.refused_connections == {}  # Origin: the public host passed
        page.get_by_role("button", name=AGREE).click()
        page.get_by_role("button", name="Start").click()
        page.get_by_role("button", name="Close the gripper (G)").wait_for()
        live = next(s for s in rs.server.sessions() if s.participant == "L0001")
        assert wait_until(lambda: live.run is not None and live.run.ticks > 0)
        before = np.array(live.run.trial.user_target, float)
        t1 = time.monotonic()
        page.keyboard.down("w")
        assert wait_until(
            lambda: np.linalg.norm(np.array(live.run.trial.user_target) - before) > 1e-3,
            timeout=5,
        )
        print(f"key press to the target moving: {time.monotonic() - t1:.2f} s")
        hold(page, "w", 1.5)
        screenshot(page, screenshots, "proxy-01-trial-at-150ms")
        moved = np.array(live.run.trial.user_target, float) - before
        assert np.linalg.norm(moved) > 0.03, moved  # the held key steered the arm
        page.wait_for_timeout(1000)  # the release travels 75 ms and more
        target = np.array(live.run.trial.user_target, float)
        page.wait_for_timeout(800)  # the release arrived: the target stays put
        assert np.allclose(live.run.trial.user_target, target, atol=1e-6)
        assert not live.run.over  # all of it within the run
    finally:
        ctx.close()

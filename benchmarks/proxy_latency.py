"""An online participant behind the TLS reverse proxy at 150 ms round trip, against a direct tab.

The study server runs with the open link on and ``trusted_proxies``; Debian's nginx terminates
TLS in front of it with the README's site (``tests/browser/test_tls_proxy.py``'s configuration
and delaying relay: 75 ms each way, from 127.0.0.2). In turns, one headless Chromium tab opens
the link directly (http, no delay) and one through relay and nginx (https); each consents,
starts the practice run and presses W/S five times. Measured per path:

* join_s: from opening the link to the consent screen (page load, websocket, link read,
  enrolment, start);
* key_ms: from a key going down in the page to the server's target moving (the key's way to
  the server plus one control tick), median and max.

Usage: ``.venv/bin/python benchmarks/proxy_latency.py [--rounds 3]``. Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from playwright.sync_api import sync_playwright

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from study.server.forwarded import trusted_networks
from tests.browser.harness import launch, start_server, wait_until
from tests.browser.test_participant_flow import AGREE
from tests.browser.test_tls_proxy import (
    CLIENT,
    MAIN,
    NGINX,
    ONE_WAY_S,
    SITE,
    DelayRelay,
    _free_port,
    _listening,
)


def measure(browser: Any, url: str, rs: Any, who: str) -> tuple[float, list[float]]:
    ctx = browser.new_context(viewport={"width": 1100, "height": 720}, ignore_https_errors=True)
    ctx.set_default_timeout(120_000)
    page = ctx.new_page()
    t0 = time.monotonic()
    page.goto(url)
    page.get_by_role("button", name=AGREE).wait_for()
    join_s = time.monotonic() - t0
    page.get_by_role("button", name=AGREE).click()
    page.get_by_role("button", name="Start").click()
    page.get_by_role("button", name="Close the gripper (G)").wait_for()
    live = next(s for s in rs.server.sessions() if s.participant == who)
    wait_until(lambda: live.run is not None and live.run.ticks > 0)
    page.wait_for_timeout(2000)
    keys = []
    for key in "wswsw":
        before = np.array(live.run.trial.user_target, float)
        t1 = time.monotonic()
        page.keyboard.down(key)
        wait_until(
            lambda b=before: np.linalg.norm(np.array(live.run.trial.user_target) - b) > 1e-4,
            timeout=10,
            interval=0.005,
        )
        keys.append(1000 * (time.monotonic() - t1))
        page.keyboard.up(key)
        page.wait_for_timeout(700)
    ctx.close()
    return join_s, keys


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="proxy-latency-"))
    rs = start_server(
        tmp,
        time_limit_s=120.0,
        training_runs=1,
        server_kw={
            "open_link": 2 * args.rounds,
            "trusted_proxies": trusted_networks(["127.0.0.1"]),
        },
    )
    cert, key = tmp / "cert.pem", tmp / "key.pem"
    subprocess.run(
        ["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
         "-subj", "/CN=localhost", "-keyout", str(key), "-out", str(cert)],
        check=True, capture_output=True,
    )  # fmt: skip
    port = _free_port()
    site = SITE.format(port=port, cert=cert, key=key, upstream=rs.server.participant_port)
    (tmp / "nginx.conf").write_text(MAIN.format(tmp=tmp, site=site))
    nginx = subprocess.Popen([NGINX, "-c", str(tmp / "nginx.conf"), "-g", "daemon off;"])
    relay = DelayRelay(target=port, delay_s=ONE_WAY_S, source=CLIENT)
    results: dict[str, dict[str, list[float]]] = {
        p: {"join_s": [], "key_ms": []} for p in ("direct", "proxy_150ms")
    }
    try:
        wait_until(lambda: _listening(port))
        relay.start()
        with sync_playwright() as p:
            browser = launch(p)
            for i in range(args.rounds):
                for path, url in (
                    ("direct", f"{rs.url}/?pid=D{i}"),
                    ("proxy_150ms", f"https://localhost:{relay.port}/?pid=X{i}"),
                ):
                    who = f"L{len(rs.store.participants()) + 1:04d}"
                    join_s, keys = measure(browser, url, rs, who)
                    results[path]["join_s"].append(join_s)
                    results[path]["key_ms"] += keys
                    print(path, f"join {join_s:.2f} s, key -> move ms", [round(k) for k in keys])
            browser.close()
    finally:
        relay.stop()
        nginx.terminate()
        rs.stop()
    summary = {
        path: {
            "join_s_median": round(float(np.median(r["join_s"])), 2),
            "key_ms_median": round(float(np.median(r["key_ms"])), 1),
            "key_ms_max": round(float(np.max(r["key_ms"])), 1),
            "n_keys": len(r["key_ms"]),
        }
        for path, r in results.items()
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()

"""The server's log grows with time, never with what clients send (issue 22).

Wrong-version handshakes once wrote a traceback each (9.9 MB of log in 10 s from one client)
and bare TCP connections 232 KB/s, on the disk that holds the store. Now every kind of line is
let through at most ten times a minute, client-driven lines never carry a traceback, and the
file is rotated with a cap on its disk use, which the console shows.
"""

from __future__ import annotations

import logging
import logging.handlers
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from study.server import logs


@pytest.fixture
def restore_logging() -> Iterator[None]:
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    yield
    for handler in root.handlers:
        handler.close()
    root.handlers[:] = handlers
    root.setLevel(level)


def _boom() -> None:
    raise ValueError("from a client's message")


def test_a_flood_of_one_kind_is_ten_lines_a_minute_and_says_how_many_were_held_back() -> None:
    bounded = logs.BoundedLines(per_minute=10)
    kept = []
    for k in range(5000):
        record = logging.LogRecord(
            "study.server.live", logging.WARNING, "f", 1, "refused %d", (k,), None
        )
        if bounded.filter(record):
            kept.append(record.getMessage())
    assert len(kept) == 10 and bounded.held_back == 4990
    bounded._windows[("study.server.live", "refused %d")][0] -= 61  # a minute later
    record = logging.LogRecord(
        "study.server.live", logging.WARNING, "f", 1, "refused %d", (1,), None
    )
    assert bounded.filter(record)
    assert record.getMessage().endswith("[4990 more like this in the last minute]")


def test_client_driven_lines_never_carry_a_traceback_and_others_once_an_hour() -> None:
    bounded = logs.BoundedLines()
    try:
        _boom()
    except ValueError:
        exc_info = sys.exc_info()
    client = logging.LogRecord(
        "websockets.server", logging.ERROR, "f", 1, "handshake failed", (), exc_info
    )
    assert bounded.filter(client) and client.exc_info is None
    ours = [
        logging.LogRecord(
            "study.server.live", logging.ERROR, "f", 1, "page update failed", (), exc_info
        )
        for _ in range(3)
    ]
    assert all(bounded.filter(r) for r in ours)
    assert ours[0].exc_info is not None and ours[1].exc_info is None and ours[2].exc_info is None


def test_the_log_file_rotates_under_a_cap(tmp_path: Path, restore_logging: None) -> None:
    path = tmp_path / "logs" / "serve.log"
    logs.configure(path, max_bytes=20_000, backups=2)
    logger = logging.getLogger("study.server.test")
    for k in range(3000):  # 3000 kinds (a client cannot make this many; the code can)
        logger.warning(f"line {k} " + "x" * 200)
    used = logs.disk_use(path, backups=2)
    assert used <= 3 * 20_000 + 1000
    assert path.with_name("serve.log.2").exists() and not path.with_name("serve.log.3").exists()

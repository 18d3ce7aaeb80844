"""The study server as ``serve`` runs it, for the tests of the participant port under attack."""

from __future__ import annotations

import pytest

from tests.browser import harness


@pytest.fixture
def served_as_serve_runs_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """Servers started by :func:`tests.browser.harness.start_server` with start-up's heap out of
    the collector (``study.server.realtime``), so that connections' garbage costs short
    collections only. (Not ``serve``'s nice -10 too: a server under a flood at that priority
    starved another worker's test of its tab's messages for 20 s.)"""
    monkeypatch.setitem(harness.SERVER_DEFAULTS, "freeze_heap", True)

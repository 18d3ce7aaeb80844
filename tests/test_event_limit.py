"""A flood of caller events (rejected input, reconnects) is capped per kind; the count survives.

10,000 rejected poses once wrote 10,200 fsync'd event rows. Now each kind written through
``Session.record_event`` passes a token bucket (10 at once, then 1 per second): events over it
are counted, the next written one carries ``"suppressed": k``, and what is still counted when the
session ends or closes is written as one ``events_suppressed`` event. The engine's own events
(trial start/end, answers, pause, resume) never pass through the limit.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from study.protocol import Protocol, load_protocol
from study.session import Session, open_store
from study.session.event_limit import DEFAULT_BURST, DEFAULT_RATE_PER_S, EventLimiter
from study.store import Store
from tests.support.sessions import enrol, to_step

PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "dragan2013.toml"


@pytest.fixture(scope="module")
def protocol() -> Protocol:
    return load_protocol(PROTOCOL)


@pytest.fixture
def store(tmp_path: Path, protocol: Protocol) -> Iterator[Store]:
    with open_store(tmp_path / "study.db", protocol) as s:
        yield s


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_bucket_admits_a_burst_then_the_rate_and_counts_the_rest() -> None:
    clock = FakeClock()
    limiter = EventLimiter(burst=3, rate_per_s=2.0, clock=clock)
    assert [limiter.admit("input_rejected") for _ in range(5)] == [0, 0, 0, None, None]
    assert limiter.admit("participant_connected") == 0  # each kind has its own bucket
    clock.now += 0.5  # one token back
    assert limiter.admit("input_rejected") == 2  # carries the two dropped meanwhile
    assert limiter.admit("input_rejected") is None
    assert limiter.pending() == {"input_rejected": 1}
    limiter.reported({"input_rejected": 1})
    assert limiter.pending() == {}
    clock.now += 60  # refills to the burst, not beyond
    assert [limiter.admit("input_rejected") for _ in range(4)] == [0, 0, 0, None]


def test_restore_puts_back_the_count_of_an_event_that_was_not_written() -> None:
    clock = FakeClock()
    limiter = EventLimiter(burst=1, rate_per_s=1.0, clock=clock)
    limiter.admit("x")
    assert limiter.admit("x") is None
    clock.now += 1
    carried = limiter.admit("x")
    assert carried == 1
    limiter.restore("x", carried)
    assert limiter.pending() == {"x": 1}


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="burst"):
        EventLimiter(burst=0)
    with pytest.raises(ValueError, match="rate_per_s"):
        EventLimiter(rate_per_s=float("nan"))


def rejected(db: Store, session: Session) -> list[dict]:
    return [
        e.detail for e in db.events(session_id=session.session_id) if e.kind == "input_rejected"
    ]


def test_a_flood_of_rejected_input_writes_a_handful_of_rows_and_keeps_the_count(
    store: Store,
    protocol: Protocol,
) -> None:
    session = enrol(store, protocol)
    session.start()
    rows_before = len(store.events())
    start = time.monotonic()
    for i in range(10_000):
        session.record_event("input_rejected", {"problem": f"pose {i} is not finite"})
    elapsed = time.monotonic() - start
    written = rejected(store, session)
    # the bucket's bound for however long the loop took (no timing is asserted)
    assert len(written) <= DEFAULT_BURST + int(elapsed * DEFAULT_RATE_PER_S) + 1
    assert len(store.events()) - rows_before == len(written)
    session.close()
    (summary,) = [e for e in store.events() if e.kind == "events_suppressed"]
    carried = sum(d.get("suppressed", 0) for d in rejected(store, session))
    assert len(written) + carried + summary.detail["counts"]["input_rejected"] == 10_000
    kinds = [e.kind for e in store.events(session_id=session.session_id)]
    assert kinds[-2:] == ["events_suppressed", "close"]


def test_engine_events_are_never_capped(store: Store, protocol: Protocol) -> None:
    session = enrol(store, protocol)
    session.start()
    for _ in range(3 * DEFAULT_BURST):
        session.pause()
        session.resume()
    kinds = [e.kind for e in store.events(session_id=session.session_id)]
    assert kinds.count("pause") == kinds.count("resume") == 3 * DEFAULT_BURST
    session.close()


def test_a_finished_session_reports_what_was_still_counted(
    store: Store,
    protocol: Protocol,
) -> None:
    session = enrol(store, protocol)
    session.start()
    for _ in range(DEFAULT_BURST + 5):
        session.record_event("tab_reconnected", {})
    to_step(session, "debrief")
    session.finish()
    events = store.events(session_id=session.session_id)
    summaries = [e for e in events if e.kind == "events_suppressed"]
    assert summaries and summaries[-1].detail["counts"].get("tab_reconnected", 0) >= 1
    reported = sum(
        e.detail.get("suppressed", 0) + 1 for e in events if e.kind == "tab_reconnected"
    ) + sum(s.detail["counts"].get("tab_reconnected", 0) for s in summaries)
    assert reported == DEFAULT_BURST + 5
    session.close()

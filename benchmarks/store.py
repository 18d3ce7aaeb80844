"""Store and session write costs: what the control loop pays per tick, what a commit takes.

Measures, for SQLite ``synchronous`` FULL and NORMAL (the store's setting for its main
connection; sample batches go through the samples' own ``NORMAL`` connection either way, so
their figures only differ by noise):

- ``add_us``: ``SampleWriter.add`` in the calling (control) thread at 100 Hz (row conversion
  and buffer append; the only store work a control tick does);
- ``insert_us_per_sample``: ``executemany`` + commit of a batch, divided by its rows, for the
  batch a 100 Hz loop fills in 100 ms (10 rows) and the one a headless loop fills (300 rows);
- ``batch_commit_ms``: the writer thread's commit of one batch at 100 Hz;
- ``transition_commit_ms``: one session transition (an event row and a cursor update);
- ``session_tick_us`` vs ``bare_tick_us``: a real training trial ticked through
  ``TrialRun.tick`` (session, sample writer) and through ``Trial.tick`` alone.

Prints a table, then one JSON object as the last line.
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.teleop import ScriptedInput  # noqa: E402
from app.trial import TickRecord, Trial  # noqa: E402
from study.protocol import load_protocol  # noqa: E402
from study.session import Session, open_store  # noqa: E402
from study.session.sample_writer import SampleWriter, sample_row  # noqa: E402
from study.store import Store  # noqa: E402


def stats(xs: list[float], scale: float) -> dict[str, float]:
    return {
        "median": round(statistics.median(xs) * scale, 3),
        "p99": round(float(np.percentile(xs, 99)) * scale, 3),
    }


def record(i: int) -> TickRecord:
    v = np.linspace(-1.0, 1.0, 7) + 0.001 * i
    return TickRecord(
        tick=i, t=i * 0.01, q=v, u=v, p=v, command=v, alpha=0.4, confidence=0.6,
        probabilities=np.array([0.3, 0.7]), predicted=1, user_target=np.zeros(3),
        ee=np.ones(3), gripper=0.04,
    )  # fmt: skip


def fresh_trial(store: Store, participant: str) -> int:
    with store.transaction() as tx:
        sid = tx.enrol(participant, schedule_row=0, assignments=[], seed=0)
        return tx.insert_trial(
            session_id=sid, participant=participant, step=1, trial_number=1, phase="training",
            mode="none", attempt=1, seed=0,
        )  # fmt: skip


def measure(synchronous: str, tmp: Path) -> dict[str, object]:
    store = Store.open(tmp / f"{synchronous}.db", protocol_id="bench", protocol_hash="0" * 64,
                       synchronous=synchronous)  # fmt: skip
    recs = [record(i) for i in range(300)]
    out: dict[str, object] = {}
    # executemany per sample, two batch sizes
    trial = fresh_trial(store, "B1")
    tick = 0
    for size in (10, 300):
        times = []
        for _ in range(40 if size == 10 else 10):
            rows = [sample_row(trial, tick + j, recs[j % 300]) for j in range(size)]
            tick += size
            t0 = time.perf_counter()
            store.insert_samples(rows)
            times.append((time.perf_counter() - t0) / size)
        out[f"insert_us_per_sample_batch{size}"] = stats(times, 1e6)
    # the writer at 100 Hz: cost of add() in the control thread, commit latency in its thread
    trial = fresh_trial(store, "B2")
    writer = SampleWriter(store, flush_interval_s=0.1)
    adds = []
    next_t = time.perf_counter()
    for i in range(500):
        t0 = time.perf_counter()
        writer.add(trial, i, recs[i % 300])
        adds.append(time.perf_counter() - t0)
        next_t += 0.01
        time.sleep(max(0.0, next_t - time.perf_counter()))
    writer.close()
    out["add_us"] = stats(adds, 1e6)
    out["batch_commit_ms"] = stats(writer.stats.commit_s, 1e3)
    out["batches"] = writer.stats.batches
    # a session transition: one event + cursor update in one transaction
    times = []
    with store.transaction() as tx:
        sid = tx.enrol("B3", schedule_row=0, assignments=[], seed=0)
    for i in range(200):
        t0 = time.perf_counter()
        with store.transaction() as tx:
            tx.event(sid, "B3", "bench", {"i": i})
            tx.update_session(sid, cursor=i)
        times.append(time.perf_counter() - t0)
    out["transition_commit_ms"] = stats(times, 1e3)
    store.close()
    return out


def tick_overhead(tmp: Path) -> dict[str, object]:
    protocol = load_protocol(ROOT / "protocols" / "dragan2013.toml")
    config = protocol.training_config()
    bare = Trial(config, ScriptedInput(seed=1), seed=1)
    bare_times = []
    while not bare.done:
        t0 = time.perf_counter()
        bare.tick()
        bare_times.append(time.perf_counter() - t0)
    store = open_store(tmp / "session.db", protocol)
    session = Session.enrol(store, protocol, "S1", seed=1)
    session.start()
    session.agree()
    run = session.start_trial(input_source=ScriptedInput(seed=1))
    times = []
    while not run.over:
        t0 = time.perf_counter()
        run.tick()
        times.append(time.perf_counter() - t0)
    times = times[:-1]  # the last tick also commits the finished trial
    session.close()
    store.close()
    return {
        "bare_tick_us": stats(bare_times, 1e6),
        "session_tick_us": stats(times, 1e6),
        "ticks": len(times),
    }


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        result = {s: measure(s, tmp) for s in ("FULL", "NORMAL")}
        result["tick"] = tick_overhead(tmp)
    for sync in ("FULL", "NORMAL"):
        r = result[sync]
        print(f"synchronous={sync}")
        for key, value in r.items():
            print(f"  {key:34s} {value}")
    print("tick (real training trial)")
    for key, value in result["tick"].items():
        print(f"  {key:34s} {value}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()

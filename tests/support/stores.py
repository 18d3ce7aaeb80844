"""Store helpers shared by the store, fault, damage and sample-layout tests: open a store for a
test protocol hash, enrol a participant, start a trial, make a tick record."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from app.trial import TickRecord
from app.trial.events import EventKind, TrialEvent
from study.store import (
    Store,
)

HASH = hashlib.sha256(b"protocol").hexdigest()


def open_store(path: Path, **kw: object) -> Store:
    return Store.open(path, protocol_id="demo", protocol_hash=HASH, protocol_version="1", **kw)


def enrol(store: Store, participant: str = "P01") -> int:
    with store.transaction() as tx:
        return tx.enrol(
            participant,
            schedule_row=0,
            assignments=[(1, "easy-right", "first", "timid"), (2, "easy-right", "second", "aggr")],
            seed=7,
            demographics={"age": 31, "gender": "f"},
        )


def tick(i: int) -> TickRecord:
    v = np.arange(7, dtype=float) + i
    return TickRecord(
        tick=i,
        t=i * 0.01,
        q=v,
        u=v + 0.1,
        p=v + 0.2,
        command=v + 0.3,
        alpha=0.5,
        confidence=0.25,
        probabilities=np.array([0.2, 0.8]),
        predicted=1,
        user_target=np.array([0.5, 0.1, 0.2]),
        ee=np.array([0.4, 0.0, 0.3]),
        gripper=0.0,
        events=(TrialEvent(EventKind.GRASP_REQUESTED),) if i == 3 else (),
    )


def new_trial(store: Store, session_id: int, *, step: int = 1, attempt: int = 1) -> int:
    with store.transaction() as tx:
        return tx.insert_trial(
            session_id=session_id,
            participant="P01",
            step=step,
            trial_number=1,
            phase="training",
            mode="none",
            attempt=attempt,
            seed=1,
            goal_names=["mug"],
            goal_positions=[[0.5, 0, 0]],
        )

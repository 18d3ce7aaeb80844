"""Typed trial events: one codec, byte-identical to the text stores and exports already hold."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.prediction_eval import goal_moves, trial_trajectories
from app.trial import records_from_samples
from app.trial.events import EventKind, TrialEvent, TrialEventError, decode, encode, mark
from study.export import tidy_tables
from study.session.sample_writer import sample_row
from study.store import SAMPLE_COLUMNS, Store
from tests.support.stores import enrol, new_trial, open_store

TODAY = (
    "paused",
    "resumed",
    "grasp_requested",
    "grasp_missed",
    "objects_disturbed",
    "invalid_target",
    "target_clamped",
    "target_far_outside",
    "timeout",
    "aborted",
    "interrupted",
    "grasped:bottle",
    "lifted:bottle",
    "dropped:bottle",
    "lift_failed:box",
    "pushed_off:box",
    "knocked_over:box",
    "outcome:success",
    "input_error:RuntimeError",
    "physics_error:mj_step: bad qacc: nan at dof 3",
    "goal_moved:box@0.512345,-0.100000,0.050000",
    "contact:hand:box",
    "contact_end:leftfinger:bottle:0.0500",
)
"""One string of every kind, exactly as the trial wrote them before events were typed."""

ADDED = ("object_reset:box",)
"""One string of every kind added since (an object stood up again after a knock)."""


def test_a_shared_mark_is_the_event_built_afresh() -> None:
    """``mark(kind)``: the payload-free event of ``kind``, built once and shared; a kind with a
    payload must be built."""
    for kind in EventKind:
        try:
            fresh = TrialEvent(kind)
        except TrialEventError:
            with pytest.raises(TrialEventError, match="payload"):
                mark(kind)
            continue
        assert mark(kind) == fresh and mark(kind) is mark(kind)
        assert encode(mark(kind)) == kind.value


def test_every_kind_round_trips_byte_for_byte() -> None:
    events = [decode(text) for text in (*TODAY, *ADDED)]
    assert {e.kind for e in events} == set(EventKind)
    assert [encode(e) for e in events] == [*TODAY, *ADDED]
    assert [decode(encode(e)) for e in events] == events
    moved = events[TODAY.index("goal_moved:box@0.512345,-0.100000,0.050000")]
    assert moved.obj == "box" and moved.position == (0.512345, -0.1, 0.05)
    end = decode("contact_end:leftfinger:bottle:0.0500")
    assert (end.part, end.obj, end.impulse_ns) == ("leftfinger", "bottle", 0.05)
    assert decode("physics_error:mj_step: bad qacc: nan at dof 3").text == (
        "mj_step: bad qacc: nan at dof 3"
    )


@pytest.mark.parametrize(
    "text",
    [
        "teleported:box",
        "grasped",
        "paused:later",
        "grasped:",
        "goal_moved:box@1,2",
        "goal_moved:box",
        "contact_end:hand:box:hard",
        "",
    ],
)
def test_unreadable_text_raises_a_typed_error_quoting_it(text: str) -> None:
    with pytest.raises(TrialEventError, match="trial event") as err:
        decode(text)
    assert repr(text) in str(err.value)


def test_an_event_carries_exactly_its_kinds_payload() -> None:
    with pytest.raises(TrialEventError, match="needs 'obj'"):
        TrialEvent(EventKind.GRASPED)
    with pytest.raises(TrialEventError, match="takes no 'obj'"):
        TrialEvent(EventKind.PAUSED, obj="box")
    with pytest.raises(TrialEventError, match="not \\(x, y, z\\)"):
        TrialEvent(EventKind.GOAL_MOVED, obj="box", position=(0.0, np.nan, 0.0))


def _old_row(trial_id: int, tick: int, events: list[str]) -> list[object]:
    """A ``samples`` row as the writer stored it before events were typed: raw JSON text."""
    values: dict[str, object] = {c: 0.0 for c in SAMPLE_COLUMNS}
    values.update(
        trial_id=trial_id,
        tick=tick,
        t=tick / 100,
        predicted=0,
        probabilities="[0.5, 0.5]",
        events=json.dumps(events),
    )
    return [values[c] for c in SAMPLE_COLUMNS]


def test_a_store_written_with_todays_strings_reads_typed_and_rewrites_identically(
    tmp_path: Path,
) -> None:
    path = tmp_path / "old.db"
    ticks = [list(TODAY[:8]), [], list(TODAY[8:16]), list(TODAY[16:])]
    with open_store(path) as store:
        tid = new_trial(store, enrol(store))
        store.insert_samples([_old_row(tid, k, evs) for k, evs in enumerate(ticks)])
    store = Store.open_readonly(path)
    samples = store.samples(tid)
    records = records_from_samples(samples)
    assert [tuple(encode(e) for e in r.events) for r in records] == [tuple(t) for t in ticks]
    # the writer stores those typed events as the very text it read
    for k, record in enumerate(records):
        row = dict(zip(SAMPLE_COLUMNS, sample_row(tid, k, record), strict=True))
        assert row["events"] == samples["events"][k]
    # export: the contact measure comes from the decoded events
    trials = tidy_tables(store)["trials"]
    assert trials["contacts"].tolist() == [1]
    assert trials["contact_impulse_ns"].tolist() == pytest.approx([0.05])
    # and the accident counts (a store from before resets: none stood up again)
    counts = trials[["knocks", "target_knocks", "pushes_off", "drops", "object_resets"]]
    assert counts.iloc[0].tolist() == [1, 0, 1, 2, 0]
    # analysis: the logged goal move is found and read
    _, _, rows = trial_trajectories(samples)[tid]
    moves = goal_moves(rows, ["bottle", "box"], tid)
    assert moves is not None and moves.rows.tolist() == [3] and moves.goals.tolist() == [1]
    assert moves.positions.tolist() == [[0.512345, -0.1, 0.05]]

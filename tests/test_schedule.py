"""Williams squares and participant schedules are balanced the way the paper's design needs."""

from __future__ import annotations

import csv
import io
import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from study.__main__ import main as study_main
from study.protocol import load_protocol
from study.schedule import (
    Design,
    Enrollment,
    ScheduleError,
    assign_rows,
    next_row,
    schedule,
    williams_square,
)
from tests.support.cli import Ran, run_main

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"


def carryover(rows) -> Counter:
    return Counter((r[i], r[i + 1]) for r in rows for i in range(len(r) - 1))


@pytest.mark.parametrize("n", range(1, 10))
def test_williams_square_is_latin_and_carryover_balanced(n: int) -> None:
    rows = williams_square(n)
    assert len(rows) == (n if n % 2 == 0 or n == 1 else 2 * n)
    for row in rows:
        assert sorted(row) == list(range(n))
    reps = len(rows) // n
    for position in range(n):
        assert Counter(r[position] for r in rows) == dict.fromkeys(range(n), reps)
    pairs = carryover(rows)
    expected = {(a, b): reps for a in range(n) for b in range(n) if a != b}
    assert dict(pairs) == expected


def test_even_square_is_balanced_with_a_single_square() -> None:
    rows = williams_square(4)
    assert len(rows) == 4
    assert set(carryover(rows).values()) == {1}


def test_odd_square_needs_its_mirror() -> None:
    rows = williams_square(3)
    first_half = rows[:3]
    assert len(carryover(first_half)) < 3 * 2  # one square alone misses some ordered pairs
    assert rows[3:] == tuple(tuple(reversed(r)) for r in first_half)
    assert dict(carryover(rows)) == {(a, b): 2 for a in range(3) for b in range(3) if a != b}


@pytest.mark.parametrize("bad", [0, -1, 2.0, True, "4"])
def test_williams_square_rejects_bad_sizes(bad) -> None:
    with pytest.raises(ScheduleError):
        williams_square(bad)


@pytest.fixture(scope="module")
def paper():
    return load_protocol(PAPER)


def test_paper_schedule_eight_participants(paper) -> None:
    trials = schedule(paper, participants=8)
    assert len(trials) == 64
    by_participant: dict[str, list] = {}
    for t in trials:
        by_participant.setdefault(t.participant, []).append(t)
    assert sorted(by_participant) == [f"P0{i}" for i in range(1, 9)]
    for rows in by_participant.values():
        assert [t.position for t in rows] == list(range(1, 9))
        # every condition exactly once; a task's two runs are back to back
        assert Counter((t.task, t.mode) for t in rows) == {
            (task, mode): 1 for task in paper.task_names for mode in paper.mode_names
        }
        tasks = [t.task for t in rows]
        assert all(tasks[2 * k] == tasks[2 * k + 1] for k in range(4))

    orders = [[t.task for t in rows][::2] for rows in by_participant.values()]
    # each task in each task position equally often (twice across 8 participants)
    for slot in range(4):
        assert Counter(o[slot] for o in orders) == dict.fromkeys(paper.task_names, 2)
    # each task immediately follows each other task equally often
    assert set(carryover(orders).values()) == {2}
    assert len(carryover(orders)) == 12
    # the order of the two modes within each task is balanced across participants
    for task in paper.task_names:
        first = Counter(t.mode for t in trials if t.task == task and t.run == 1)
        assert first == {"timid": 4, "aggressive": 4}
    # ... and each participant starts half of the tasks with each mode
    for rows in by_participant.values():
        assert Counter(t.mode for t in rows if t.run == 1) == {"timid": 2, "aggressive": 2}


def test_odd_number_of_tasks_and_three_modes() -> None:
    design = Design(tasks=("a", "b", "c"), modes=("x", "y", "z"))
    assert design.cycle == 6 * 6
    trials = schedule(design, participants=design.cycle)
    orders: dict[str, list[str]] = {}
    for t in trials:
        if t.run == 1:
            orders.setdefault(t.participant, []).append(t.task)
    assert set(carryover(orders.values()).values()) == {12}
    for slot in range(3):
        assert Counter(o[slot] for o in orders.values()) == dict.fromkeys("abc", 12)
    for task in "abc":
        for run in (1, 2, 3):
            got = Counter(t.mode for t in trials if t.task == task and t.run == run)
            assert got == dict.fromkeys("xyz", 12)


def test_rows_beyond_one_cycle_repeat_it(paper) -> None:
    design = Design.from_protocol(paper)
    assert design.cycle == 8
    assert design.row_trials(3) == tuple(
        t.__class__(**{**t.__dict__, "row": 3}) for t in design.row_trials(11)
    )


def test_next_row_hands_out_rows_in_order() -> None:
    assert next_row([]) == 0
    assert next_row([("p1", False), ("p2", False)]) == 2


def test_withdrawn_row_goes_to_the_next_enrollment() -> None:
    history = [("p1", False), ("p2", True)]
    assert next_row(history) == 1
    history.append(("p3", False))
    assert assign_rows(history) == [0, 1, 1]
    assert next_row(history) == 2
    # Several withdrawals: the lowest freed row first.
    history = [Enrollment("a", row=0), Enrollment("b", True, 1), Enrollment("c", True, 2)]
    assert next_row(history) == 1
    history.append(Enrollment("d", row=1))
    assert next_row(history) == 2
    history.append(Enrollment("e", row=2))
    assert next_row(history) == 3


def test_rows_skipped_by_an_override_are_filled() -> None:
    history = [Enrollment("a", row=2), Enrollment("b", row=0)]
    assert next_row(history) == 1
    history.append(Enrollment("c", row=1))
    assert next_row(history) == 3


def test_enrollment_history_errors() -> None:
    with pytest.raises(ScheduleError, match="enrolled twice"):
        next_row([("p1", False), ("p1", False)])
    with pytest.raises(ScheduleError, match="held by an active participant"):
        next_row([Enrollment("a", row=0), Enrollment("b", row=0)])


@given(st.lists(st.booleans(), max_size=40))
def test_active_participants_always_hold_distinct_rows_without_gaps(withdrawn) -> None:
    history = [(f"p{i}", w) for i, w in enumerate(withdrawn)]
    rows = assign_rows(history)
    active = [r for r, w in zip(rows, withdrawn, strict=True) if not w]
    assert len(active) == len(set(active))
    nxt = next_row(history)
    assert nxt not in active
    # the active rows plus the next one fill 0..k with no gap: balance is kept
    assert sorted([*active, nxt]) == list(range(len(active) + 1))


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study", "schedule", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def run_here(capsys: pytest.CaptureFixture[str], *args: str) -> Ran:
    """``python -m study schedule``'s ``main`` in this process: what it returns and prints,
    without an interpreter's start-up and imports (about 1.2 CPU s a command). The first
    command of :func:`test_cli_csv_and_json` and the one run from another folder stay new
    processes, as a user runs them."""
    return run_main(study_main, ["schedule", *args], capsys)


def test_cli_csv_and_json(paper, capsys: pytest.CaptureFixture[str]) -> None:
    out = run_cli("--protocol", str(PAPER), "--participants", "8", "--format", "csv")
    assert out.returncode == 0, out.stderr
    rows = list(csv.DictReader(io.StringIO(out.stdout)))
    assert list(rows[0]) == ["participant", "position", "task", "mode"]
    assert len(rows) == 64
    expected = schedule(paper, participants=8)
    assert [(r["participant"], int(r["position"]), r["task"], r["mode"]) for r in rows] == [
        (t.participant, t.position, t.task, t.mode) for t in expected
    ]
    out = run_here(capsys, "--protocol", str(PAPER), "--participants", "8", "--format", "json")
    assert out.returncode == 0, out.stderr
    records = json.loads(out.stdout)
    assert records == [{k: r[k] if k != "position" else int(r[k]) for k in r} for r in rows]


def test_cli_defaults_to_the_planned_sample_size(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_here(capsys, "--protocol", str(PAPER))
    assert out.returncode == 0, out.stderr
    assert len(out.stdout.strip().splitlines()) == 1 + 64


def test_cli_reports_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = run_here(capsys, "--protocol", str(PAPER), "--participants", "0")
    assert out.returncode == 2 and "--participants: must be 1..10000, got 0" in out.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text(PAPER.read_text().replace("runs = 3", "runs = 'three'"))
    out = run_here(capsys, "--protocol", str(bad), "--participants", "8")
    assert out.returncode == 2
    assert f"{bad}: training.runs: expected an integer" in out.stderr


def test_cli_default_protocol_from_any_directory(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "study", "schedule", "--participants", "8"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert out.returncode == 0, out.stderr
    assert len(out.stdout.strip().splitlines()) == 1 + 64

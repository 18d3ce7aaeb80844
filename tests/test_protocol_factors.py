"""Factors by name: what a protocol declares is what the study runs, schedules and exports.

The paper's protocol keeps its three within factors; the shipped protocols of issue 25 add a
factor crossed with the modes (intent_mode), one between subjects (mapping_mode) and one that
sets the task under the williams scheme (goals_mode). Bad designs fail on load naming the keys.
"""

from __future__ import annotations

import itertools
from collections import Counter
from pathlib import Path

import pytest

from study.protocol import (
    ConditionConflictError,
    ProtocolError,
    ProtocolValueError,
    load_protocol,
    parse_protocol,
)
from study.schedule import Design, schedule

ROOT = Path(__file__).resolve().parents[1]
PROTOCOLS = ROOT / "protocols"
PAPER = load_protocol(PROTOCOLS / "dragan2013.toml")
INTENT = load_protocol(PROTOCOLS / "intent_mode.toml")
MAPPING = load_protocol(PROTOCOLS / "mapping_mode.toml")
GOALS = load_protocol(PROTOCOLS / "goals_mode.toml")
MAPPING_TEXT = (PROTOCOLS / "mapping_mode.toml").read_text()
INTENT_TEXT = (PROTOCOLS / "intent_mode.toml").read_text()


def test_the_paper_declares_three_within_factors_and_runs_as_before() -> None:
    assert PAPER.factors == {
        "difficulty": ("easy", "hard"),
        "correctness": ("right", "wrong"),
        "mode": ("timid", "aggressive"),
    }
    assert PAPER.within_factors == ("difficulty", "correctness", "mode")
    assert PAPER.between_factors == ()
    assert PAPER.scheme == "nested"
    assert PAPER.group_names == ("",)
    assert PAPER.mode_names == ("timid", "aggressive")
    assert PAPER.levels("hard-wrong", "aggressive", row=5) == {
        "difficulty": "hard",
        "correctness": "wrong",
        "mode": "aggressive",
    }
    assert Design.from_protocol(PAPER).cycle == 8


def test_a_factor_crossed_with_the_modes_sets_what_its_level_says() -> None:
    assert INTENT.factors["cue"] == ("cue_off", "cue_on")
    assert len(INTENT.modes) == 4  # mode x cue
    shown = INTENT.trial_config("easy-wrong", "aggressive-cue_on")
    hidden = INTENT.trial_config("easy-wrong", "aggressive-cue_off")
    assert shown.extra["intent"] == "goal" and hidden.extra["intent"] == "none"
    assert dict(shown.arbitration) == dict(hidden.arbitration)  # the mode's, both
    assert INTENT.levels("easy-wrong", "timid-cue_on", row=0) == {
        "difficulty": "easy",
        "correctness": "wrong",
        "mode": "timid",
        "cue": "cue_on",
    }
    # every task is done in all four mode x cue runs, back to back (nested scheme)
    trials = Design.from_protocol(INTENT).row_trials(3)
    for task, runs in itertools.groupby(trials, key=lambda t: t.task):
        assert sorted(t.mode for t in runs) == sorted(INTENT.mode_names), task


def test_a_between_factor_sets_every_run_of_its_participants_and_fills_its_groups_equally() -> None:
    assert MAPPING.between_factors == ("mapping",)
    design = Design.from_protocol(MAPPING)
    assert design.cycle == 16 and MAPPING.study.participants == 16
    groups = Counter(MAPPING.group_for(row).name for row in range(design.cycle))
    assert groups == {"absolute": 8, "relative": 8}
    assert MAPPING.group_for(1).label == "mapping=relative"  # what the console shows
    assert PAPER.group_for(1).label == ""
    relative = next(r for r in range(design.cycle) if MAPPING.group_for(r).name == "relative")
    assert MAPPING.training_config(row=relative).extra["input_mapping"] == "relative"
    assert MAPPING.trial_config("hard-wrong", "timid", row=relative).extra["input_mapping"] == (
        "relative"
    )
    assert MAPPING.trial_config("hard-wrong", "timid", row=0).extra["input_mapping"] == ("absolute")
    # within each group, the paper's 8 orders each once per cycle
    for group in ("absolute", "relative"):
        orders = {
            tuple((t.task, t.mode) for t in design.row_trials(r))
            for r in range(design.cycle)
            if MAPPING.group_for(r).name == group
        }
        assert len(orders) == 8


def test_the_williams_scheme_balances_position_and_carry_over_of_every_condition() -> None:
    design = Design.from_protocol(GOALS)
    assert GOALS.scheme == "williams" and design.cycle == 4
    rows = [[(t.task, t.mode) for t in design.row_trials(r)] for r in range(design.cycle)]
    conditions = set(itertools.product(GOALS.task_names, GOALS.mode_names))
    for position in range(4):
        assert {row[position] for row in rows} == conditions
    pairs = Counter((a, b) for row in rows for a, b in itertools.pairwise(row))
    assert set(pairs.values()) == {1} and len(pairs) == 4 * 3  # each ordered pair once
    # an odd number of conditions takes the square and its mirror: each pair twice
    odd = Design(tasks=("a",), modes=("x", "y", "z"), scheme="williams")
    odd_rows = [[t.mode for t in odd.row_trials(r)] for r in range(odd.cycle)]
    assert odd.cycle == 6
    assert set(Counter(p for row in odd_rows for p in itertools.pairwise(row)).values()) == {2}
    # runs count a task's runs so far even when they are not back to back
    assert [t.run for t in design.row_trials(1)] == [1, 1, 2, 2]


def test_a_sample_that_fills_no_whole_cycle_is_refused_with_what_a_cycle_is() -> None:
    text = MAPPING_TEXT.replace("participants = 16", "participants = 8", 1)
    with pytest.raises(ProtocolValueError, match=r"2 groups x 4 task orders x 2 mode orders"):
        parse_protocol(text)


def test_two_levels_that_set_one_value_differently_are_named_both() -> None:
    text = MAPPING_TEXT.replace(
        'levels.absolute = { input_mapping = "absolute" }',
        'levels.absolute = { input_mapping = "absolute", intent = "none" }',
    ).replace(
        "[modes.aggressive]\narbitration",
        '[modes.aggressive]\nintent = "goal"\narbitration',
    )
    with pytest.raises(ConditionConflictError) as info:
        parse_protocol(text)
    message = str(info.value)
    assert "factors.mapping.levels.absolute" in message and "aggressive" in message
    assert "intent" in message
    # two within factors crossed into one run
    text = INTENT_TEXT.replace(
        "[factors.cue]",
        '[factors.ring]\nlevels.ring_a = { intent = "goal" }\n\n[factors.cue]',
    )
    with pytest.raises(ConditionConflictError, match=r"factors\.ring\.levels\.ring_a"):
        parse_protocol(text)


@pytest.mark.parametrize(
    ("old", "new", "key", "problem"),
    [
        (
            'levels.absolute = { input_mapping = "absolute" }',
            'levels.absolute = { scene = "easy" }',
            "factors.mapping.levels",
            "between-subjects factor sets how runs go",
        ),
        ('mode = ["timid", "aggressive"]', 'style = ["timid", "aggressive"]', "factors.mode", ""),
        (
            'levels.relative = { input_mapping = "relative" }',
            'levels.relative = { input_mapping = "sideways" }',
            "factors.mapping.levels.relative.input_mapping",
            "'sideways' is not one of",
        ),
        (
            'subjects = "between"',
            'subjects = "sometimes"',
            "factors.mapping.subjects",
            "not one of within, between",
        ),
    ],
)
def test_a_bad_factor_is_refused_naming_its_key(old: str, new: str, key: str, problem: str) -> None:
    assert old in MAPPING_TEXT
    with pytest.raises(ProtocolError) as info:
        parse_protocol(MAPPING_TEXT.replace(old, new, 1))
    assert info.value.key == key
    assert problem in info.value.problem


def test_a_preference_between_runs_needs_the_nested_scheme() -> None:
    text = (PROTOCOLS / "goals_mode.toml").read_text()
    text = text.replace("between_tasks = [{", 'after_task = ["preference"]\nbetween_tasks = [{', 1)
    with pytest.raises(ProtocolValueError, match="after_task"):
        parse_protocol(text)


def test_schedules_of_the_new_protocols_give_every_participant_every_within_condition() -> None:
    for protocol in (INTENT, MAPPING, GOALS):
        n = protocol.study.participants
        trials = schedule(protocol, participants=n)
        for participant, rows in itertools.groupby(trials, key=lambda t: t.participant):
            done = sorted((t.task, t.mode) for t in rows)
            expected = sorted(itertools.product(protocol.task_names, protocol.mode_names))
            assert done == expected, (protocol.id, participant)

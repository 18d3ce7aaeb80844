"""Bad protocol files fail on load with a typed error naming the file, the key and the problem."""

from __future__ import annotations

import copy
import json
import re
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from study.protocol import (
    BlindingError,
    MissingKeyError,
    ProtocolError,
    ProtocolSyntaxError,
    ProtocolTypeError,
    ProtocolValueError,
    ScaleMismatchError,
    UndefinedReferenceError,
    UnknownKeyError,
    load_protocol,
)

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"
TEXT = PAPER.read_text()
DATA = tomllib.loads(TEXT)
MEMORY3 = tomllib.loads((ROOT / "protocols" / "memory3.toml").read_text())

# The bad protocols are built by editing the parsed paper protocol and writing it back, so the
# tests hold whatever values the protocol is tuned to; only syntax errors edit the text.
Edit = Callable[[dict[str, Any]], None]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _key(name: str) -> str:
    return name if _BARE_KEY.fullmatch(name) else json.dumps(name)


def _value(v: Any) -> str:
    """A TOML value: the subset protocol files use (strings, numbers, booleans, arrays, tables)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # JSON string escapes are TOML basic strings
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"no TOML for {v!r}")


def dumps(doc: dict[str, Any], prefix: tuple[str, ...] = ()) -> str:
    """TOML text for ``doc``: its values, then each sub-table under its own header."""
    lines = [f"{_key(k)} = {_value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    for k, v in doc.items():
        if isinstance(v, dict):
            name = (*prefix, k)
            lines += ["", f"[{'.'.join(map(_key, name))}]", dumps(v, name)]
    return "\n".join(lines)


def _parent(doc: dict[str, Any], key: str) -> tuple[dict[str, Any], str]:
    *path, last = key.split(".")
    for name in path:
        doc = doc[name]
    return doc, last


def put(key: str, value: Any) -> Edit:
    """Set (or add) the value at the dotted ``key``."""

    def edit(doc: dict[str, Any]) -> None:
        table, last = _parent(doc, key)
        table[last] = value

    return edit


def change(key: str, f: Callable[[Any], Any]) -> Edit:
    """Replace the value at ``key`` by ``f(value)``."""

    def edit(doc: dict[str, Any]) -> None:
        table, last = _parent(doc, key)
        table[last] = f(table[last])

    return edit


def rename(key: str, new: str) -> Edit:
    """Move the value at ``key`` to the sibling key ``new``."""

    def edit(doc: dict[str, Any]) -> None:
        table, last = _parent(doc, key)
        table[new] = table.pop(last)

    return edit


def drop(key: str) -> Edit:
    def edit(doc: dict[str, Any]) -> None:
        table, last = _parent(doc, key)
        del table[last]

    return edit


def edited(
    tmp_path: Path, *edits: Edit, base: dict[str, Any] = DATA, name: str = "study.toml"
) -> Path:
    """``base`` (the paper's protocol) with ``edits`` applied, written as TOML."""
    doc = copy.deepcopy(base)
    for edit in edits:
        edit(doc)
    path = tmp_path / name
    path.write_text(dumps(doc))
    return path


def broken_line(tmp_path: Path, key: str, new: str) -> Path:
    """The paper's protocol text with the one line ``key = ...`` (whatever its value) replaced
    by ``new``: for syntax errors, which parsed data cannot express."""
    pattern = re.compile(rf"^{re.escape(key)} = .*$", re.MULTILINE)
    assert len(pattern.findall(TEXT)) == 1, key
    path = tmp_path / "study.toml"
    path.write_text(pattern.sub(lambda _: new, TEXT))
    return path


def expect(path: Path, cls: type[ProtocolError], key: str, problem: str) -> ProtocolError:
    with pytest.raises(cls) as info:
        load_protocol(path)
    err = info.value
    assert err.file == str(path)
    assert err.key == key
    assert problem in err.problem
    assert str(err).startswith(f"{path}: {key}: ")
    return err


_PERIOD = 1.0 / DATA["control"]["rate_hz"]
_HELPFULNESS = DATA["questionnaire"]["scales"]["helpfulness"]["anchors"]
_AFTER_RUN = DATA["questionnaire"]["after_run"]
_HARD_GOALS = len(DATA["scenes"]["hard"]["objects"])

CASES = [
    # (edit, error class, key, problem fragment)
    (
        rename("modes.timid.arbitration.alpha_max", "alpha_maz"),
        UnknownKeyError,
        "modes.timid.arbitration.alpha_maz",
        "unknown key 'alpha_maz'",
    ),
    (put("training.secne", "x"), UnknownKeyError, "training.secne", "unknown"),
    (put("consnet", {"x": 1}), UnknownKeyError, "consnet", "unknown"),
    (
        put("control.rate_hz", "fast"),
        ProtocolTypeError,
        "control.rate_hz",
        "expected a number, got a string",
    ),
    (put("training.runs", 2.5), ProtocolTypeError, "training.runs", "expected an integer"),
    (put("training.runs", True), ProtocolTypeError, "training.runs", "got a boolean"),
    (put("training.runs", 0), ProtocolValueError, "training.runs", "must be >= 1"),
    (
        put("modes.aggressive.arbitration.alpha_high", 1.5),
        ProtocolValueError,
        "modes.aggressive.arbitration.alpha_high",
        "must be in (0, 1], got 1.5",
    ),
    (change("confidence.D", lambda d: -d), ProtocolValueError, "confidence.D", "must be in (0, 5]"),
    (
        put("control.physics_dt", _PERIOD / 2.5),
        ProtocolValueError,
        "control.physics_dt",
        "whole number of times",
    ),
    (put("policy.kind", "spline"), ProtocolValueError, "policy.kind", "'spline' is not one of"),
    (
        put("control.on_knock", "ignore"),
        ProtocolValueError,
        "control.on_knock",
        "'ignore' is not one of reset, end",
    ),
    (
        put("control.input_mapping", "rate"),
        ProtocolValueError,
        "control.input_mapping",
        "'rate' is not one of absolute, relative",
    ),
    (
        put("tasks.hard-wrong.scene", "hrad"),
        UndefinedReferenceError,
        "tasks.hard-wrong.scene",
        "scene 'hrad' is not defined",
    ),
    (
        put("tasks.hard-wrong.difficulty", "medium"),
        UndefinedReferenceError,
        "tasks.hard-wrong.difficulty",
        "'medium' is not a level",
    ),
    (
        put("tasks.hard-wrong.correctness", "right"),
        ProtocolValueError,
        "tasks.hard-wrong",
        "same difficulty and correctness as task",
    ),
    (put("training.scene", "nowhere"), UndefinedReferenceError, "training.scene", "not defined"),
    (
        put("factors.mode", ["timid", "aggressive", "bold"]),
        UndefinedReferenceError,
        "modes.bold",
        "needs a [modes.bold] table",
    ),
    (put("factors.mode", ["timid", "timid"]), ProtocolValueError, "factors.mode", "listed twice"),
    (put("factors.mode", ["timid"]), UnknownKeyError, "modes.aggressive", "unknown key"),
    (
        rename("prediction.wrong", "wrnog"),
        UndefinedReferenceError,
        "prediction.wrong",
        "needs a [prediction.wrong] table; is [prediction.wrnog] a misspelling of it?",
    ),
    (
        rename("modes.aggressive", "agressive"),
        UndefinedReferenceError,
        "modes.aggressive",
        "needs a [modes.aggressive] table; is [modes.agressive] a misspelling of it?",
    ),
    (
        change("questionnaire.scales.helpfulness.anchors", lambda a: a[:-1]),
        ScaleMismatchError,
        "questionnaire.scales.helpfulness.anchors",
        f"{len(_HELPFULNESS) - 1} anchors for a {DATA['questionnaire']['points']}-point "
        "questionnaire",
    ),
    (
        change("questionnaire.after_run", lambda items: [*items[:-1], "fun"]),
        UndefinedReferenceError,
        f"questionnaire.after_run[{len(_AFTER_RUN) - 1}]",
        "item 'fun' is not defined",
    ),
    (
        put("questionnaire.items.teammate.scale", "team"),
        UndefinedReferenceError,
        "questionnaire.items.teammate.scale",
        "scale 'team' is not defined",
    ),
    (
        change("instructions.rating", lambda text: "{who}, " + text),
        ProtocolValueError,
        "instructions.rating",
        "unknown placeholder {who}",
    ),
    (
        change("instructions.pause", lambda text: text + " (timid mode)"),
        BlindingError,
        "instructions.pause",
        "condition word(s) ['timid']",
    ),
    (
        change(
            "questionnaire.scales.preference.anchors",
            lambda a: [*a[:3], a[3] + ", all right", *a[4:]],
        ),
        BlindingError,
        "questionnaire.scales.preference.anchors[3]",
        "['right']",
    ),
    (
        change("debrief.text", lambda text: "That was hard. " + text),
        BlindingError,
        "debrief.text",
        "['hard']",
    ),
    (put("instructions.welcom", "x"), UnknownKeyError, "instructions.welcom", "unknown"),
    (
        put("prediction.wrong", {"kind": "memory", "prior": [1] * (_HARD_GOALS + 1)}),
        ProtocolValueError,
        "prediction.wrong.prior",
        str(_HARD_GOALS + 1),
    ),
    (
        put("prediction.wrong", {"kind": "laplace", "cost": "length"}),
        ProtocolValueError,
        "prediction.wrong.cost",
        "squared_velocity",
    ),
    (
        put("modes.timid.arbitration.alpha_max", 0.0),
        ProtocolValueError,
        "modes.timid.arbitration.alpha_max",
        "must be in (0, 1)",
    ),
    (
        put("training.prediction", {"kind": "oracle", "goal": "cup"}),
        UnknownKeyError,
        "training.prediction.goal",
        "unknown key 'goal'",
    ),
    (
        change("study.participants", lambda n: n + 1),
        ProtocolValueError,
        "study.participants",
        "use a multiple of 8",
    ),  # one balanced cycle: 4 task orders x 2 mode orders
    (
        rename("factors.difficulty", "dificulty"),
        UnknownKeyError,
        "factors.dificulty",
        "unknown key 'dificulty'",
    ),
    (change("schema", lambda v: v + 1), ProtocolValueError, "schema", "reads schema 1"),
    (drop("schema"), MissingKeyError, "schema", "required key is missing"),
]


def test_the_writer_round_trips_the_protocols() -> None:
    for doc in (DATA, MEMORY3):
        assert tomllib.loads(dumps(doc)) == doc


@pytest.mark.parametrize(("edit", "cls", "key", "problem"), CASES)
def test_bad_protocol_is_rejected_with_file_key_and_problem(
    tmp_path: Path, edit: Edit, cls: type[ProtocolError], key: str, problem: str
) -> None:
    expect(edited(tmp_path, edit), cls, key, problem)


def test_control_options_reach_every_trial(tmp_path: Path) -> None:
    paper = load_protocol(PAPER)  # defaults: knocks are reset, the handle is absolute
    assert (paper.control.on_knock, paper.control.input_mapping) == ("reset", "absolute")
    path = edited(
        tmp_path, put("control.on_knock", "end"), put("control.input_mapping", "relative")
    )
    protocol = load_protocol(path)
    for config in (protocol.trial_config("hard-wrong", "aggressive"), protocol.training_config()):
        assert config.on_knock == "end" and config.extra["input_mapping"] == "relative"


def test_duplicate_key_names_the_line(tmp_path: Path) -> None:
    line = next(i for i, text in enumerate(TEXT.splitlines(), 1) if text.startswith("runs = "))
    path = broken_line(tmp_path, "runs", "runs = 3\nruns = 4")
    with pytest.raises(ProtocolSyntaxError) as info:
        load_protocol(path)
    err = info.value
    assert err.key == f"line {line + 1} (runs)"
    assert "defined twice" in err.problem
    assert str(path) in str(err)


def test_duplicate_table_is_a_syntax_error(tmp_path: Path) -> None:
    assert TEXT.count("[modes.aggressive]") == 1
    path = tmp_path / "study.toml"
    path.write_text(TEXT.replace("[modes.aggressive]", "[modes.timid]"))
    with pytest.raises(ProtocolSyntaxError, match="defined twice"):
        load_protocol(path)


def test_invalid_toml_is_a_syntax_error(tmp_path: Path) -> None:
    path = broken_line(tmp_path, "runs", "runs = ")
    with pytest.raises(ProtocolSyntaxError, match="invalid TOML"):
        load_protocol(path)


def test_scene_errors_name_the_scene_key(tmp_path: Path) -> None:
    path = edited(tmp_path, put("scenes.training.target", "cup"))
    err = expect(path, ProtocolValueError, "scenes.training.target", "'cup' is not one of")
    assert isinstance(err, ProtocolError)


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(ProtocolError, match="cannot read the file") as info:
        load_protocol(tmp_path / "absent.toml")
    assert info.value.file == str(tmp_path / "absent.toml")


def test_preference_needs_two_modes(tmp_path: Path) -> None:
    three_modes = (
        put("factors.mode", ["timid", "aggressive", "bold"]),
        put("study.participants", 24),  # 4 task x 6 mode orders
        put("modes.bold", {"arbitration": {"kind": "linear", "alpha_max": 0.8}}),
    )
    path = edited(tmp_path, *three_modes, name="three_modes.toml")
    expect(path, ProtocolValueError, "questionnaire.after_task", "needs exactly 2 modes")
    path = edited(
        tmp_path, *three_modes, put("questionnaire.after_task", []), name="three_modes.toml"
    )
    assert load_protocol(path).mode_names == ("timid", "aggressive", "bold")


def test_every_difficulty_correctness_cell_needs_a_task(tmp_path: Path) -> None:
    path = edited(tmp_path, drop("tasks.hard-wrong"), name="three_tasks.toml")
    expect(
        path,
        UndefinedReferenceError,
        "tasks",
        "no task has difficulty = 'hard' and correctness = 'wrong'",
    )


def test_object_names_must_not_name_a_level_of_this_protocol(tmp_path: Path) -> None:
    objects = MEMORY3["scenes"]["three"]["objects"]
    i = len(objects) - 1
    renamed = [*objects[:i], {**objects[i], "name": "memory-card"}]
    path = edited(tmp_path, put("scenes.three.objects", renamed), base=MEMORY3, name="memory3.toml")
    expect(path, BlindingError, f"scenes.three.objects[{i}].name", "['memory']")


def test_target_description_is_checked_for_this_protocols_levels(tmp_path: Path) -> None:
    path = edited(
        tmp_path,
        change("instructions.task", lambda text: text + " (linear)"),
        base=MEMORY3,
        name="memory3.toml",
    )
    expect(path, BlindingError, "instructions.task", "['linear']")

"""Bad protocol files fail on load with a typed error naming the file, the key and the problem."""

from __future__ import annotations

from pathlib import Path

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


def broken(tmp_path: Path, old: str, new: str, *, name: str = "study.toml") -> Path:
    """The paper's protocol with ``old`` (which must occur once) replaced by ``new``."""
    assert TEXT.count(old) == 1, old
    path = tmp_path / name
    path.write_text(TEXT.replace(old, new))
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


CASES = [
    # (old, new, error class, key, problem fragment)
    ("alpha_max = 0.5", "alpha_maz = 0.5", UnknownKeyError, "modes.timid.arbitration.alpha_maz",
     "unknown key 'alpha_maz'"),
    ("[training]\n", "[training]\nsecne = 'x'\n", UnknownKeyError, "training.secne", "unknown"),
    ("[consent]\n", "[consnet]\nx = 1\n[consent]\n", UnknownKeyError, "consnet", "unknown"),
    ("rate_hz = 100", 'rate_hz = "fast"', ProtocolTypeError, "control.rate_hz",
     "expected a number, got a string"),
    ("runs = 3", "runs = 2.5", ProtocolTypeError, "training.runs", "expected an integer"),
    ("runs = 3", "runs = true", ProtocolTypeError, "training.runs", "got a boolean"),
    ("runs = 3", "runs = 0", ProtocolValueError, "training.runs", "must be >= 1"),
    ("alpha_high = 0.9", "alpha_high = 1.5", ProtocolValueError,
     "modes.aggressive.arbitration.alpha_high", "must be <= 1.0"),
    ("D = 0.4", "D = -0.4", ProtocolValueError, "confidence.D", "must be > 0"),
    ("physics_dt = 0.002", "physics_dt = 0.003", ProtocolValueError, "control.physics_dt",
     "whole number of times"),
    ('kind = "straight_line"', 'kind = "spline"', ProtocolValueError, "policy.kind",
     "'spline' is not one of"),
    ('correctness = "wrong"\nscene = "hard"', 'correctness = "wrong"\nscene = "hrad"',
     UndefinedReferenceError, "tasks.hard-wrong.scene", "scene 'hrad' is not defined"),
    ('difficulty = "hard"\ncorrectness = "wrong"', 'difficulty = "medium"\ncorrectness = "wrong"',
     UndefinedReferenceError, "tasks.hard-wrong.difficulty", "'medium' is not a level"),
    ('difficulty = "hard"\ncorrectness = "wrong"', 'difficulty = "hard"\ncorrectness = "right"',
     ProtocolValueError, "tasks.hard-wrong", "same difficulty and correctness as task"),
    ('scene = "training"', 'scene = "nowhere"', UndefinedReferenceError, "training.scene",
     "not defined"),
    ('mode = ["timid", "aggressive"]', 'mode = ["timid", "aggressive", "bold"]',
     UndefinedReferenceError, "modes.bold", "needs a [modes.bold] table"),
    ('mode = ["timid", "aggressive"]', 'mode = ["timid", "timid"]', ProtocolValueError,
     "factors.mode", "listed twice"),
    ('mode = ["timid", "aggressive"]', 'mode = ["timid"]', UnknownKeyError, "modes.aggressive",
     "unknown key"),
    ("[prediction.wrong]", "[prediction.wrnog]", UndefinedReferenceError, "prediction.wrong",
     "correctness level 'wrong' needs"),
    ('"Quite helpful", "Very helpful", "Extremely helpful",',
     '"Very helpful", "Extremely helpful",',
     ScaleMismatchError, "questionnaire.scales.helpfulness.anchors",
     "6 anchors for a 7-point questionnaire"),
    ('after_run = ["helpful", "matched", "teammate"]', 'after_run = ["helpful", "matched", "fun"]',
     UndefinedReferenceError, "questionnaire.after_run[2]", "item 'fun' is not defined"),
    ('scale = "teammate"', 'scale = "team"', UndefinedReferenceError,
     "questionnaire.items.teammate.scale", "scale 'team' is not defined"),
    ('rating = "Please', 'rating = "{who}, please', ProtocolValueError, "instructions.rating",
     "unknown placeholder {who}"),
    ('pause = "The session is paused.', 'pause = "The session is paused (timid mode).',
     BlindingError, "instructions.pause", "condition word(s) ['timid']"),
    ('"No preference"', '"No preference, all right"', BlindingError,
     "questionnaire.scales.preference.anchors[3]", "['right']"),
    ("[debrief]\ntext = \"\"\"\n", "[debrief]\ntext = \"\"\"\nThat was hard. ", BlindingError,
     "debrief.text", "['hard']"),
    ("[instructions]\nwelcome", "[instructions]\nwelcom = 'x'\nwelcome", UnknownKeyError,
     "instructions.welcom", "unknown"),
    ('kind = "amnesic"\nspace = "workspace"\ntemperature = 0.05',
     'kind = "memory"\nprior = [1, 1, 1]', ProtocolValueError, "prediction.wrong.prior",
     "3"),
    ('kind = "amnesic"\nspace = "workspace"\ntemperature = 0.05',
     'kind = "laplace"\ncost = "length"', ProtocolValueError, "prediction.wrong.cost",
     "squared_velocity"),
    ("alpha_max = 0.5", "alpha_max = 0.0", ProtocolValueError,
     "modes.timid.arbitration.alpha_max", "must be in (0, 1)"),
    ('{ kind = "oracle" }', '{ kind = "oracle", goal = "cup" }', UnknownKeyError,
     "training.prediction.goal", "unknown key 'goal'"),
    ("participants = 8", "participants = 12", ProtocolValueError, "study.participants",
     "use a multiple of 8"),
    ('difficulty = ["easy", "hard"]', 'dificulty = ["easy", "hard"]', UnknownKeyError,
     "factors.dificulty", "unknown key 'dificulty'"),
    ("schema = 1", "schema = 2", ProtocolValueError, "schema", "reads schema 1"),
    ("schema = 1\n", "", MissingKeyError, "schema", "required key is missing"),
]


@pytest.mark.parametrize(("old", "new", "cls", "key", "problem"), CASES)
def test_bad_protocol_is_rejected_with_file_key_and_problem(
    tmp_path: Path, old: str, new: str, cls: type[ProtocolError], key: str, problem: str
) -> None:
    expect(broken(tmp_path, old, new), cls, key, problem)


def test_duplicate_key_names_the_line(tmp_path: Path) -> None:
    path = broken(tmp_path, "runs = 3\n", "runs = 3\nruns = 4\n")
    with pytest.raises(ProtocolSyntaxError) as info:
        load_protocol(path)
    err = info.value
    line = TEXT.splitlines().index("runs = 3") + 2
    assert err.key == f"line {line} (runs)"
    assert "defined twice" in err.problem
    assert str(path) in str(err)


def test_duplicate_table_is_a_syntax_error(tmp_path: Path) -> None:
    path = broken(tmp_path, "[modes.aggressive]", "[modes.timid]")
    with pytest.raises(ProtocolSyntaxError, match="defined twice"):
        load_protocol(path)


def test_invalid_toml_is_a_syntax_error(tmp_path: Path) -> None:
    path = broken(tmp_path, "runs = 3", "runs = ")
    with pytest.raises(ProtocolSyntaxError, match="invalid TOML"):
        load_protocol(path)


def test_scene_errors_name_the_scene_key(tmp_path: Path) -> None:
    path = broken(tmp_path, 'target = "mug"', 'target = "cup"')
    err = expect(path, ProtocolValueError, "scenes.training.target", "'cup' is not one of")
    assert isinstance(err, ProtocolError)


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(ProtocolError, match="cannot read the file") as info:
        load_protocol(tmp_path / "absent.toml")
    assert info.value.file == str(tmp_path / "absent.toml")


def test_preference_needs_two_modes(tmp_path: Path) -> None:
    text = TEXT.replace('mode = ["timid", "aggressive"]', 'mode = ["timid", "aggressive", "bold"]')
    text = text.replace("participants = 8 ", "participants = 24 ")  # 4 task x 6 mode orders
    text = text.replace(
        "[training]\n",
        '[modes.bold]\narbitration = { kind = "linear", alpha_max = 0.8 }\n\n[training]\n',
    )
    path = tmp_path / "three_modes.toml"
    path.write_text(text)
    expect(path, ProtocolValueError, "questionnaire.after_task", "needs exactly 2 modes")
    path.write_text(text.replace('after_task = ["preference"]', "after_task = []"))
    assert load_protocol(path).mode_names == ("timid", "aggressive", "bold")


def test_every_difficulty_correctness_cell_needs_a_task(tmp_path: Path) -> None:
    start = TEXT.index("[tasks.hard-wrong]")
    end = TEXT.index("[prediction.right]")
    path = tmp_path / "three_tasks.toml"
    path.write_text(TEXT[:start] + TEXT[end:])
    expect(path, UndefinedReferenceError, "tasks",
           "no task has difficulty = 'hard' and correctness = 'wrong'")


def test_object_names_must_not_name_a_level_of_this_protocol(tmp_path: Path) -> None:
    text = (ROOT / "protocols" / "memory3.toml").read_text()
    old = '{ name = "can",'
    assert text.count(old) == 1
    path = tmp_path / "memory3.toml"
    path.write_text(text.replace(old, '{ name = "memory-card",'))
    expect(path, BlindingError, "scenes.three.objects[2].name", "['memory']")


def test_target_description_is_checked_for_this_protocols_levels(tmp_path: Path) -> None:
    text = (ROOT / "protocols" / "memory3.toml").read_text()
    path = tmp_path / "memory3.toml"
    path.write_text(text.replace('task = "Pick up the {target}.', 'task = "Pick up the {target}'
                                 ' (linear).'))
    expect(path, BlindingError, "instructions.task", "['linear']")

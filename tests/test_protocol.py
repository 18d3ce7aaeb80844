"""The paper's protocol loads complete, and its pieces are what the study engine needs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import app
from app.trial.config import TrialConfig
from study.protocol import (
    TRAINING_MODE,
    AnswerError,
    ConditionError,
    LikertItem,
    load_protocol,
    parse_protocol,
)
from study.schedule import Design, schedule

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"
MEMORY3 = ROOT / "protocols" / "memory3.toml"
BLINDED = ("timid", "aggressive", "right", "wrong", "easy", "hard")


@pytest.fixture(scope="module")
def paper():
    return load_protocol(PAPER)


def test_paper_design_is_two_by_two_by_two(paper) -> None:
    assert paper.factors == {
        "difficulty": ("easy", "hard"),
        "correctness": ("right", "wrong"),
        "mode": ("timid", "aggressive"),
    }
    cells = {(t.difficulty, t.correctness) for t in paper.tasks}
    assert cells == {("easy", "right"), ("easy", "wrong"), ("hard", "right"), ("hard", "wrong")}
    assert paper.task_names == ("easy-right", "easy-wrong", "hard-right", "hard-wrong")
    assert paper.training.runs == 3
    assert paper.study.id == "dragan2013"
    assert paper.software_version == app.__version__


def test_paper_prediction_confidence_and_arbitration(paper) -> None:
    assert dict(paper.prediction["right"]) == {"kind": "oracle"}
    wrong = paper.prediction["wrong"]
    assert wrong["kind"] == "amnesic" and wrong["space"] == "workspace"
    assert paper.confidence["kind"] == "distance" and paper.confidence["D"] > 0
    timid = paper.mode("timid").arbitration
    aggressive = paper.mode("aggressive").arbitration
    assert timid["kind"] == "timid" and 0 < timid["alpha_max"] < 1
    assert aggressive["kind"] == "aggressive"
    # Fig. 7: aggressive takes more control than timid ever does, once confident enough.
    assert aggressive["alpha_high"] > timid["alpha_max"]


def test_hard_scene_puts_the_target_outside_the_reach_region(paper) -> None:
    for task in paper.tasks:
        scene = paper.scenes[task.scene]
        target = scene.object(scene.target).position
        box = zip(scene.reach_lo, target, scene.reach_hi, strict=True)
        inside = all(lo <= x <= hi for lo, x, hi in box)
        assert inside == (task.difficulty == "easy"), task.name
        # The target is always the farther of the objects from the robot's base.
        distances = {o.name: sum(x * x for x in o.position[:2]) for o in scene.objects}
        assert max(distances, key=distances.get) == scene.target


@pytest.mark.parametrize("task", ["easy-right", "easy-wrong", "hard-right", "hard-wrong"])
@pytest.mark.parametrize("mode", ["timid", "aggressive"])
def test_trial_config_of_every_condition(paper, task: str, mode: str) -> None:
    config = paper.trial_config(task, mode)
    assert isinstance(config, TrialConfig)
    t = paper.task(task)
    assert config.scene.name == t.scene
    assert config.prediction["kind"] == ("oracle" if t.correctness == "right" else "amnesic")
    assert config.arbitration["kind"] == mode
    assert config.confidence["kind"] == "distance"
    assert config.task == task and config.mode == mode
    assert config.time_limit_s == paper.control.time_limit_s
    assert config.extra["content_hash"] == paper.content_hash


def test_training_config_is_unassisted(paper) -> None:
    config = paper.training_config()
    assert config.arbitration is None and not config.assisted
    assert config.mode == TRAINING_MODE == "none"
    assert config.scene.name == "training"
    assert config.scene.target not in paper.scenes["easy"].object_names


def test_unknown_task_or_mode_is_a_condition_error(paper) -> None:
    with pytest.raises(ConditionError, match="no task 'medium'"):
        paper.trial_config("medium", "timid")
    with pytest.raises(ConditionError, match="no mode 'bold'"):
        paper.trial_config("easy-right", "bold")


def test_trial_descriptions_never_name_a_condition(paper) -> None:
    descriptions = {t.name: paper.describe_trial(t.name) for t in paper.tasks}
    for task, text in descriptions.items():
        low = text.lower()
        assert not [w for w in BLINDED if w in low], (task, text)
        assert task not in text
        assert "box" in text  # the target of every task (Fig. 6)
    # Nothing about the description distinguishes the four task types.
    assert len(set(descriptions.values())) == 1
    training = paper.describe_training()
    assert "mug" in training and not [w for w in BLINDED if w in training.lower()]


def test_every_participant_facing_text_is_blinded(paper) -> None:
    texts = [paper.consent_text, paper.debrief_text, paper.texts.consent_agree]
    texts += list(paper.texts.instructions.values())
    for item in paper.questionnaire.items.values():
        texts += [*item.texts(), *(item.scale.anchors if isinstance(item, LikertItem) else ())]
    assert len(texts) > 60
    for text in texts:
        assert not [w for w in BLINDED if w in text.lower()], text


def test_questionnaire_matches_the_paper(paper) -> None:
    q = paper.questionnaire
    assert q.points == 7
    assert [i.id for i in q.after_run] == ["helpful", "matched", "teammate"]
    assert [i.id for i in q.after_training] == ["helpful", "matched", "teammate"]
    assert [i.id for i in q.after_task] == ["preference"]
    for item in q.items.values():
        if isinstance(item, LikertItem):
            assert item.scale.points == 7 and len(set(item.scale.anchors)) == 7
    pref = q.item("preference").scale.anchors
    assert pref[0] == "Strongly preferred the first run"
    assert pref[-1] == "Strongly preferred the second run"
    assert q.item("preference").scale.midpoint == 4


def test_answers_are_checked_against_the_scale(paper) -> None:
    q = paper.questionnaire
    assert q.check_answer("helpful", 7) == 7
    assert q.check_answer("helpful", 3.0) == 3
    for bad in (0, 8, 2.5, True, "4", None):
        with pytest.raises(AnswerError, match="helpful"):
            q.check_answer("helpful", bad)
    with pytest.raises(AnswerError, match="no questionnaire item 'fun'"):
        q.check_answer("fun", 4)
    assert q.check_answers("after_run", {"helpful": 5, "matched": 4, "teammate": 6}) == {
        "helpful": 5,
        "matched": 4,
        "teammate": 6,
    }
    with pytest.raises(AnswerError, match="missing \\['teammate'\\]"):
        q.check_answers("after_run", {"helpful": 5, "matched": 4})


def test_content_hash_ignores_formatting_but_not_content() -> None:
    text = PAPER.read_text()
    base = parse_protocol(text).content_hash
    assert re.fullmatch(r"[0-9a-f]{64}", base)
    reformatted = "# a comment\n" + text.replace("rate_hz = 100", "rate_hz   =   100")
    assert parse_protocol(reformatted).content_hash == base
    assert load_protocol(PAPER).content_hash == base
    changed = text.replace("runs = 3", "runs = 4")
    assert parse_protocol(changed).content_hash != base


def test_memory3_protocol_loads_and_schedules() -> None:
    p = load_protocol(MEMORY3)
    assert p.mode_names == ("timid", "linear", "aggressive")
    assert p.task_names == ("amnesic", "memory", "oracle")
    assert len(p.scenes["three"].objects) == 3
    assert p.prediction["memory"]["kind"] == "memory"
    assert p.questionnaire.points == 5 and p.questionnaire.after_task == ()
    # A mode may bring its own confidence measure.
    assert p.trial_config("memory", "aggressive").confidence["kind"] == "distance"
    assert p.trial_config("memory", "timid").confidence["kind"] == "probability"
    assert p.task("oracle").time_limit_s == 60 and p.task("memory").time_limit_s == 90
    design = Design.from_protocol(p)
    assert design.cycle == 36
    trials = schedule(p, participants=design.cycle)
    assert len(trials) == 36 * 9
    for task in p.tasks:
        assert not [w for w in p.condition_words if w in p.describe_trial(task.name).lower()]

"""Questionnaire items beyond Likert: the protocol format, the answers a session accepts and
refuses, the simulated participants' answers, and the data-retention answer honoured by export
and analysis."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from analysis.load import from_store
from analysis.results import analyse
from analysis.sections.data import data_section
from study.export import export_metadata, tidy_tables
from study.protocol import (
    AnswerError,
    AttentionItem,
    BlindingError,
    ChoiceItem,
    NumberItem,
    ProtocolValueError,
    RetentionItem,
    TextItem,
    UndefinedReferenceError,
    load_protocol,
    parse_protocol,
)
from study.session import open_store
from study.session.answers import ScriptedAnswers
from study.session.errors import InvalidAnswerError
from study.session.headless import run_headless
from study.simulated import load_population
from study.simulated.participant import SimulatedParticipant
from tests.protocol_copies import PAPER_PROTOCOL
from tests.support.sessions import enrol, finish_run, to_step, valid_answers
from tests.support.simulated_people import lived, screen

TEXT = PAPER_PROTOCOL.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def shipped() -> Any:
    return load_protocol(PAPER_PROTOCOL)


def edited(old: str, new: str) -> str:
    assert old in TEXT, old
    return TEXT.replace(old, new, 1)


# -- the protocol format ------------------------------------------------------------------------


def test_shipped_protocol_asks_demographics_attention_comment_and_retention(shipped) -> None:
    q = shipped.questionnaire
    assert [i.id for i in q.before_training] == [
        "age_band",
        "gender",
        "handedness",
        "robot_experience",
        "game_hours",
    ]
    assert all(isinstance(i, ChoiceItem) for i in q.before_training[:4])
    hours = q.item("game_hours")
    assert isinstance(hours, NumberItem) and hours.unit == "hours per week" and not hours.whole
    ((after, (attention,)),) = q.between_tasks
    assert after == 2 and isinstance(attention, AttentionItem)
    assert attention.correct in attention.options and attention.correct in attention.prompt
    comment, retention = q.closing
    assert isinstance(comment, TextItem) and comment.optional and comment.max_length == 1000
    assert isinstance(retention, RetentionItem) and q.retention is retention
    assert "kept only if you agree" in shipped.consent_text  # what the question honours
    assert "only if you agree" in retention.prompt


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ('"No, with my other hand"', '"Right-handed"', "handedness.options[1]"),
        ('unit = "hours per week"', 'unit = "hours on easy games"', "game_hours.unit"),
        ('prompt = "How old are you?"', 'prompt = "How hard was it?"', "age_band.prompt"),
    ],
)
def test_blinding_covers_options_units_and_prompts(old: str, new: str, key: str) -> None:
    with pytest.raises(BlindingError) as err:
        parse_protocol(edited(old, new))
    assert err.value.key == f"questionnaire.items.{key}"


@pytest.mark.parametrize(
    ("old", "new", "error", "message"),
    [
        ('correct = "Somewhat"', 'correct = "Often"', ProtocolValueError, "not one of the"),
        (
            '"robot_experience", "game_hours"]',
            '"robot_experience", "game_hours", "keep_data"]',
            ProtocolValueError,
            "belongs at the end of the study",
        ),
        (
            'after_run = ["helpful", "matched", "teammate"]',
            'after_run = ["helpful", "gender"]',
            ProtocolValueError,
            "holds rating-scale (likert) items only",
        ),
        ("after_task = 2, items", "after_task = 4, items", ProtocolValueError, "use closing"),
        (
            'closing = ["comment", "keep_data"]',
            'closing = ["comment", "keep_data", "age_band"]',
            ProtocolValueError,
            "already asked in before_training",
        ),
        (
            "minimum = 0\nmaximum = 100",
            "minimum = 0\nmaximum = 0",
            ProtocolValueError,
            "must be above minimum",
        ),
        ("max_length = 1000", "max_length = 5000", ProtocolValueError, "must be <= 2000"),
        ('type = "text"', 'type = "essay"', ProtocolValueError, "not one of likert"),
        (
            'closing = ["comment", "keep_data"]',
            'closing = ["comment", "keep"]',
            UndefinedReferenceError,
            "'keep' is not defined",
        ),
    ],
)
def test_questionnaire_errors_name_the_key(old: str, new: str, error: type, message: str) -> None:
    with pytest.raises(error, match=re.escape(message)):
        parse_protocol(edited(old, new))


def test_closing_instruction_is_required_when_closing_items_are_asked() -> None:
    with pytest.raises(Exception, match="closing"):
        parse_protocol(edited('closing = "Last questions before you finish."\n', ""))


# -- answers ------------------------------------------------------------------------------------


def test_answers_are_checked_and_errors_never_quote_the_typed_text(shipped) -> None:
    q = shipped.questionnaire
    hours, comment = q.item("game_hours"), q.item("comment")
    assert hours.check("7,5") == 7.5 and hours.check(" 12 ") == 12.0 and hours.check(0) == 0
    for bad in ("right", "101", "-1", "nan", "1e400", True, "1" * 40):
        with pytest.raises(AnswerError) as err:
            hours.check(bad)
        assert "a number from 0 to 100 (hours per week)" in str(err.value)
        assert "right" not in str(err.value)
    assert comment.check("  it felt right\r\nthanks\x00 ") == "it felt right\nthanks"
    assert comment.check("   ") is None  # optional, left empty
    with pytest.raises(AnswerError, match="has 1001 characters; at most 1000") as err:
        comment.check("hard " * 200 + "x")
    assert "hard" not in str(err.value)
    with pytest.raises(AnswerError, match="one of its 7 options"):
        q.item("age_band").check("the wrong one")
    with pytest.raises(AnswerError, match="needs an answer"):
        q.item("keep_data").check("")
    assert q.item("attention").passed("Somewhat") and not q.item("attention").passed("A little")


def test_bad_answers_are_refused_and_the_session_goes_on(tmp_path: Path, shipped) -> None:
    store = open_store(tmp_path / "s.db", shipped)
    session = enrol(store, shipped)
    to_step(session, "questions", questionnaire="before_training")
    good = valid_answers(session.screen().items)
    for bad in ({"game_hours": 250}, {"game_hours": "many"}, {"age_band": "17"}):
        with pytest.raises(InvalidAnswerError):
            session.answer({**good, **bad})
        assert store.answers() == [] and session.screen().questionnaire == "before_training"
    screen_after = session.answer(good)
    assert screen_after.phase == "ready"
    kinds = {a.item: (a.kind, a.value, a.number) for a in store.answers()}
    assert kinds["game_hours"] == ("number", "0", 0.0)
    assert kinds["age_band"] == ("choice", "18-24", None)
    session.close()
    store.close()


def test_simulated_participants_answer_every_kind_without_changing_their_ratings() -> None:
    def person() -> SimulatedParticipant:
        return SimulatedParticipant(load_population().draw(3, seed=5))

    shipped = load_protocol(PAPER_PROTOCOL)
    q = shipped.questionnaire
    a, b = person(), person()
    about = a.answer(_screen("before_training", q.before_training))
    assert set(about) == {i.id for i in q.before_training}
    assert about["age_band"] in q.item("age_band").options and 0 <= about["game_hours"] <= 100
    for p in (a, b):
        for d in (8.0, 7.0, 6.0):
            lived(p, duration=d)
        lived(p, duration=5.0)
    rating = screen("after_training", "helpful", "matched", "teammate")
    assert a.answer(rating) == b.answer(rating)  # the extra answers drew from their own stream
    closing = a.answer(_screen("closing", q.closing))
    assert closing == {"comment": None, "keep_data": q.retention.keep}


def _screen(moment: str, items: Any) -> Any:
    base = screen(moment)
    return type(base)(**{**base.__dict__, "items": tuple(items)})


# -- data retention: export and analysis --------------------------------------------------------


class Declines(ScriptedAnswers):
    """Scripted answers, but "No" to keeping the data."""

    def answer(self, screen: Any) -> dict[str, Any]:
        out = super().answer(screen)
        for item in screen.items:
            if isinstance(item, RetentionItem):
                out[item.id] = next(o for o in item.options if o != item.keep)
        return out


def test_a_declined_or_missing_retention_answer_leaves_the_participant_out(
    tmp_path: Path, shipped
) -> None:
    store = open_store(tmp_path / "s.db", shipped)
    for participant, answerer in (("P01", ScriptedAnswers(seed=1)), ("P02", Declines(seed=2))):
        session = enrol(store, shipped, participant)
        run_headless(session, answerer=answerer)
        session.close()
    session = enrol(store, shipped, "P03")
    to_step(session, "ready")
    session.withdraw(reason="had to leave")
    session.close()
    session = enrol(store, shipped, "P04")
    to_step(session, "ready")
    finish_run(session)  # still under way: not asked yet
    session.close()
    tables = tidy_tables(store)
    p = tables["participants"].set_index("participant")
    assert list(p["included"]) == [True, False, False, True]
    assert p.loc["P04", "status"] == "running" and pd_isna(p.loc["P04", "retention"])
    assert p.loc["P02", "excluded_because"].startswith("declined data retention")
    assert "did not answer" in p.loc["P03", "excluded_because"]
    assert "withdrawn" in p.loc["P03", "excluded_because"]
    assert p.loc["P01", "age_band"] in shipped.questionnaire.item("age_band").options
    assert p.loc["P01", "attention_checks"] == 1 and p.loc["P01", "attention_failures"] == 0
    assert pd_isna(p.loc["P02", "age_band"])  # nothing of theirs but the reason
    for name in ("trials", "answers"):
        assert set(tables[name]["participant"]) == {"P01", "P04"}, name
    assert set(tables["ratings"]["participant"]) == {"P01"}  # P04 has rated nothing yet
    assert set(tables["events"]["participant"].dropna()) == {"P01", "P04"}
    trial_ids = set(tables["trials"]["trial_id"])
    assert set(tables["samples"]["trial_id"]) <= trial_ids
    meta = export_metadata(store, tables, protocol=shipped)
    assert set(meta["excluded_participants"]) == {"P02", "P03"}
    assert meta["retention_pending"] == ["P04"]
    store.close()
    analysed = from_store(tmp_path / "s.db")
    assert set(analysed.trials["participant"]) == {"P01", "P04"}
    assert any("P02" in n and "declined" in n for n in analysed.notes)
    data = data_section(analyse(analysed, predictors={}), analysed, successful_only=False)
    assert data.paragraphs[0].startswith("4 participant(s) enrolled, 2 included; left out: P02")
    assert "session still under way: P04" in data.paragraphs[0]


def pd_isna(value: Any) -> bool:
    import pandas as pd

    return bool(pd.isna(value))

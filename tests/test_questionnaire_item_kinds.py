"""Questionnaire item kinds: a kind defined here alone is read from a protocol, checks its
answers, is answered by simulated participants and stored through a whole simulated session."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from study.protocol import AnswerError, ProtocolValueError, parse_protocol
from study.protocol.errors import UnknownKeyError
from study.protocol.item_kinds import ItemKind, register_item_kind, unregister_item_kind
from study.session import open_store
from study.session.answers import profile_answer
from study.simulated import simulate
from tests.protocol_copies import PAPER_PROTOCOL, short_protocol


@dataclass(frozen=True)
class YesNoItem:
    """Yes or no, typed (any case, spaces around); stored as ``yes`` or ``no``."""

    id: str
    prompt: str
    optional: bool = False
    kind: ClassVar[str] = "yes_no"

    def texts(self) -> tuple[str, ...]:
        return (self.prompt,)

    def check(self, value: object) -> str | None:
        word = value.strip().lower() if isinstance(value, str) else None
        if word in ("yes", "no"):
            return word
        if not word and self.optional:
            return None
        raise AnswerError(f"item {self.id!r}: answer yes or no")

    def sample(self, rng: np.random.Generator) -> str:
        return "yes" if rng.random() < 0.5 else "no"


YES_NO = ItemKind(
    name="yes_no",
    keys=("optional",),
    read=lambda item_id, prompt, table, scales: YesNoItem(
        id=item_id, prompt=prompt, optional=table.boolean("optional", False)
    ),
    doc="yes or no",
)

ITEM = """
[questionnaire.items.drove]
type = "yes_no"
prompt = "Have you ever steered a machine with a joystick?"
"""


@pytest.fixture
def yes_no() -> Iterator[ItemKind]:
    register_item_kind(YES_NO)
    try:
        yield YES_NO
    finally:
        unregister_item_kind("yes_no")


def _with_item(text: str, *, extra: str = "") -> str:
    text = text.replace(
        'before_training = ["age_band"', 'before_training = ["drove", "age_band"', 1
    )
    return text + ITEM + extra


def test_a_kind_defined_here_is_read_checked_and_answered(yes_no) -> None:
    protocol = parse_protocol(_with_item(PAPER_PROTOCOL.read_text(encoding="utf-8")))
    q = protocol.questionnaire
    item = q.item("drove")
    assert isinstance(item, YesNoItem) and item in q.before_training
    assert q.check_answer("drove", " Yes ") == "yes"
    with pytest.raises(AnswerError, match="yes or no"):
        q.check_answer("drove", "maybe")
    assert profile_answer(item, np.random.default_rng(0)) in ("yes", "no")


def test_its_table_takes_only_its_keys(yes_no) -> None:
    text = _with_item(PAPER_PROTOCOL.read_text(encoding="utf-8"), extra="options = []\n")
    with pytest.raises(UnknownKeyError, match=r"drove\.options"):
        parse_protocol(text)


def test_an_unregistered_kind_is_refused() -> None:
    with pytest.raises(ProtocolValueError, match="yes_no"):
        parse_protocol(_with_item(PAPER_PROTOCOL.read_text(encoding="utf-8")))


def test_simulated_participants_answer_it_into_the_store(yes_no, tmp_path: Path) -> None:
    path = short_protocol(tmp_path, asked_once=True, training_runs=1)
    path.write_text(_with_item(path.read_text(encoding="utf-8")), encoding="utf-8")
    db = tmp_path / "sim.db"
    report = simulate(protocol_path=path, db=db, participants=1, seed=2, progress=False)
    assert report.errors == [] and report.participants == 1
    protocol = parse_protocol(path.read_text(encoding="utf-8"), path=path)
    store = open_store(db, protocol)
    try:
        answers = [a for a in store.answers() if a.item == "drove"]
    finally:
        store.close()
    assert [(a.kind, a.value in ("yes", "no")) for a in answers] == [("yes_no", True)]

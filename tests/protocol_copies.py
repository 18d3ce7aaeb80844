"""Shortened copies of the shipped protocols, so tests walk through whole sessions quickly."""

from __future__ import annotations

import re
from pathlib import Path

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"
PAPER_PROTOCOL = PROTOCOLS / "dragan2013.toml"
STUDY_PROTOCOLS = (
    PAPER_PROTOCOL,
    PROTOCOLS / "memory3.toml",
    PROTOCOLS / "adaptive.toml",
    PROTOCOLS / "intent.toml",
    PROTOCOLS / "intent_mode.toml",
    PROTOCOLS / "mapping_mode.toml",
    PROTOCOLS / "goals_mode.toml",
)
"""Every shipped study protocol (protocols/population.toml describes simulated people)."""
PAGE_BLINDED_PROTOCOLS = tuple(p for p in STUDY_PROTOCOLS if p.stem != "goals_mode")
"""The protocols a real browser is walked through for blinding (tests/browser/test_blinding.py):
all but goals_mode, whose page is the paper's with two more objects and whose words
(goals2, goals4) the unit tests check against every text; each costs 15-20 s of the browser
lane."""


def short_protocol(
    directory: Path | str,
    *,
    time_limit_s: float = 20,
    training_runs: int | None = None,
    source: Path = PAPER_PROTOCOL,
    asked_once: bool = False,
) -> Path:
    """Write a copy of the protocol ``source`` (protocols/dragan2013.toml by default) into
    ``directory`` whose trials (all of them: the [control] limit and any task's or training's
    own) time out after ``time_limit_s`` and, if given, with ``training_runs`` practice runs;
    return its path. The questions asked once per participant (demographics, attention check,
    comment, data retention) are left out unless ``asked_once``: tests of them ask for them."""
    text = source.read_text(encoding="utf-8")
    if not asked_once:
        text = _without_asked_once(text)
    text, n = re.subn(r"(?m)^time_limit_s = \S+", f"time_limit_s = {time_limit_s:g}", text)
    assert n >= 1, "the protocol's [control] time_limit_s moved: update tests/protocol_copies.py"
    if training_runs is not None:
        text, n = re.subn(r"(?m)^runs = \d+", f"runs = {training_runs}", text)
        assert n == 1, "the protocol's [training] runs moved: update tests/protocol_copies.py"
    path = Path(directory) / "short.toml"
    path.write_text(text, encoding="utf-8")
    return path


def relative_copy(directory: Path | str) -> Path:
    """protocols/dragan2013.toml with ``[control] input_mapping = "relative"``, in ``directory``."""
    text, n = re.subn(
        r'(?m)^input_mapping = "absolute"', 'input_mapping = "relative"', PAPER_PROTOCOL.read_text()
    )
    assert n == 1, "the protocol's [control] input_mapping moved: update tests/protocol_copies.py"
    path = Path(directory) / "relative.toml"
    path.write_text(text, encoding="utf-8")
    return path


def with_completion(path: Path, *, code: str = "", redirect_url: str = "") -> Path:
    """Add an online study's ``completion_code`` and ``redirect_url`` to the protocol at
    ``path`` (in place; either may be left out); return ``path``."""
    text = path.read_text(encoding="utf-8")
    lines = ([f"completion_code = {code!r}"] if code else []) + (
        [f"redirect_url = {redirect_url!r}"] if redirect_url else []
    )
    text, n = re.subn(r"(?m)^\[debrief\]\n", "[debrief]\n" + "".join(f"{x}\n" for x in lines), text)
    assert n == 1, "the protocol's [debrief] table moved: update tests/protocol_copies.py"
    path.write_text(text, encoding="utf-8")
    return path


def ratings_only(source: Path = PAPER_PROTOCOL) -> str:
    """The text of ``source`` asking only its rating-scale items (after training, after each
    run and after each task): the questions asked once per participant (demographics, the
    attention check, the closing comment and the data-retention question) are not asked. For
    tests of the session's state machine, whose step numbers are the paper's."""
    return _without_asked_once(source.read_text(encoding="utf-8"))


def _without_asked_once(text: str) -> str:
    text, n = re.subn(r"(?m)^(before_training|between_tasks|closing) = \[.*\]\n", "", text)
    assert n in (0, 3), "the protocol's once-asked questionnaire lists moved: update this helper"
    return text


def each_target_once(path: Path, *, mode: str = "timid") -> Path:
    """Cut the protocol at ``path`` (in place) to each target once after the practice: the
    correctness level ``right`` only (tasks easy-right and hard-right: the box on the table and
    the box at the reach's edge) and the one mode ``mode``; no preference item (it compares two
    modes), the attention check between the two tasks. Return ``path``."""
    text = path.read_text(encoding="utf-8")
    other = "aggressive" if mode == "timid" else "timid"
    edits = (
        (r'(?m)^correctness = \["right", "wrong"\]$', 'correctness = ["right"]'),
        (r'(?m)^mode = \["timid", "aggressive"\]$', f'mode = ["{mode}"]'),
        (r"(?ms)^\[tasks\.(easy|hard)-wrong\]\n.*?\n\n", ""),
        (r"(?ms)^\[prediction\.wrong\]\n.*?\n\n", ""),
        (rf"(?m)^\[modes\.{other}\]\n.*\n\n", ""),
        (r'(?m)^after_task = \["preference"\]$', "after_task = []"),
    )
    for pattern, new in edits:
        text, n = re.subn(pattern, new, text)
        assert n >= 1, f"{pattern!r} no longer matches the protocol: update this helper"
    # (a copy without the questions asked once has no attention check to move)
    text = re.sub(
        r"(?m)^between_tasks = \[\{ after_task = 2,", "between_tasks = [{ after_task = 1,", text
    )
    path.write_text(text, encoding="utf-8")
    return path


def short_practice(path: Path, *, seconds: float) -> Path:
    """Give the practice runs of the protocol at ``path`` (in place) their own time limit of
    ``seconds`` (``[training] time_limit_s``), for tests that only wait a practice run out.
    Return ``path``."""
    text = path.read_text(encoding="utf-8")
    assert "[training]\n" in text, "the protocol has no [training] table: update this helper"
    text = text.replace("[training]\n", f"[training]\ntime_limit_s = {seconds:g}\n", 1)
    path.write_text(text, encoding="utf-8")
    return path

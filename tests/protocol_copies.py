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
)
"""Every shipped study protocol (protocols/population.toml describes simulated people)."""


def short_protocol(
    directory: Path | str,
    *,
    time_limit_s: float = 20,
    training_runs: int | None = None,
    source: Path = PAPER_PROTOCOL,
) -> Path:
    """Write a copy of the protocol ``source`` (protocols/dragan2013.toml by default) into
    ``directory`` whose trials (all of them: the [control] limit and any task's or training's
    own) time out after ``time_limit_s`` and, if given, with ``training_runs`` practice runs;
    return its path."""
    text = source.read_text(encoding="utf-8")
    text, n = re.subn(r"(?m)^time_limit_s = \S+", f"time_limit_s = {time_limit_s:g}", text)
    assert n >= 1, "the protocol's [control] time_limit_s moved: update tests/protocol_copies.py"
    if training_runs is not None:
        text, n = re.subn(r"(?m)^runs = \d+", f"runs = {training_runs}", text)
        assert n == 1, "the protocol's [training] runs moved: update tests/protocol_copies.py"
    path = Path(directory) / "short.toml"
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

"""Shortened copies of the paper's protocol, so tests walk through whole sessions quickly."""

from __future__ import annotations

import re
from pathlib import Path

PAPER_PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "dragan2013.toml"


def short_protocol(
    directory: Path | str,
    *,
    time_limit_s: float = 20,
    training_runs: int | None = None,
    source: Path = PAPER_PROTOCOL,
) -> Path:
    """Write a copy of ``source`` (default protocols/dragan2013.toml) into ``directory`` whose
    trials time out after ``time_limit_s`` and, if given, with ``training_runs`` practice runs;
    return its path."""
    text = Path(source).read_text(encoding="utf-8")
    text, n = re.subn(r"(?m)^time_limit_s = \S+", f"time_limit_s = {time_limit_s:g}", text)
    assert n == 1, "the protocol's [control] time_limit_s moved: update tests/protocol_copies.py"
    if training_runs is not None:
        text, n = re.subn(r"(?m)^runs = \d+", f"runs = {training_runs}", text)
        assert n == 1, "the protocol's [training] runs moved: update tests/protocol_copies.py"
    path = Path(directory) / "short.toml"
    path.write_text(text, encoding="utf-8")
    return path

"""A command line's ``main`` run in this process, as a test that is not about the process sees
it: exit code, stdout and stderr, like :class:`subprocess.CompletedProcess` (without paying a
new interpreter's start-up and imports, 1-3 CPU s a command)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import pytest


@dataclass(frozen=True)
class Ran:
    returncode: int
    stdout: str
    stderr: str


def run_main(
    main: Callable[[Sequence[str]], int], argv: Sequence[str], capsys: pytest.CaptureFixture[str]
) -> Ran:
    """``main(argv)``'s exit code (argparse's ``SystemExit`` included) and what it printed."""
    capsys.readouterr()  # what came before is not this command's
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse: a bad value, --help
        code = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return Ran(int(code or 0), out, err)

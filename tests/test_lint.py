"""The code base passes ruff (the lint config lives in pyproject.toml)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CODE = [
    p
    for p in ("app", "study", "analysis", "tests", "benchmarks", "examples")
    if (ROOT / p).exists()
]


def test_ruff_check_passes() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "check", *CODE],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_ruff_format_leaves_every_file_as_it_is() -> None:
    """One code style: ``ruff format`` (line length 100, pyproject.toml) would change nothing.
    Run ``.venv/bin/ruff format app study analysis tests benchmarks examples`` to fix."""
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "format", "--check", *CODE],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr

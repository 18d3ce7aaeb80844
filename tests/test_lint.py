"""The code base passes ruff (the lint config lives in pyproject.toml)."""

from __future__ import annotations

import ast
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


MAX_COMPLEXITY = 12
MAX_LINES = 80


def test_no_function_is_too_complex_to_read() -> None:
    """No function in app, study or analysis over McCabe complexity 12 (ruff's C901)."""
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ruff",
            "check",
            "--select",
            "C901",
            "--config",
            f"lint.mccabe.max-complexity={MAX_COMPLEXITY}",
            "--output-format",
            "concise",
            "app",
            "study",
            "analysis",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_no_function_is_longer_than_a_screen_without_saying_why() -> None:
    """A function of app, study or analysis over 80 lines says why in its docstring
    ("Long because ...")."""
    long = []
    for path in sorted(
        p for layer in ("app", "study", "analysis") for p in (ROOT / layer).rglob("*.py")
    ):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            lines = (node.end_lineno or node.lineno) - node.lineno + 1
            if lines > MAX_LINES and "Long because" not in (ast.get_docstring(node) or ""):
                long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, "functions over 80 lines with no reason given:\n" + "\n".join(long)

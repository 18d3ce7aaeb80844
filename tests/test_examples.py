"""Every script in examples/ runs as a user would run it and prints what it promises.

Each runs as a subprocess from the repository root (``python examples/NN_name.py``) and must
exit 0; its output is checked for the figures it exists to show. A new example must be listed
in ``EXPECTED``, so none goes untested.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
EXPECTED = {
    "01_blend_tick_2d.py": [
        r"predicted goal:\s+cup",
        r"alpha\(c\):\s+0\.\d+\s+\(custom arbitration",
        r"command:\s+\[",
    ],
    "02_headless_trial.py": [
        r"outcome: success after \d+\.\d+ s simulated",
        r"\d+ control ticks at 100 Hz",
        r"mean alpha 0\.\d+",
    ],
    "03_simulated_study.py": [
        r"simulated 4 participants: 4\d trials",
        r"report: \d+ figures",
        r"\d+ tests in report\.html",
        r"timing_ancova\s+mode",
    ],
}


def test_every_example_is_listed_and_opens_with_what_it_shows() -> None:
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert scripts == sorted(EXPECTED)
    for name in scripts:
        assert re.fullmatch(r"\d\d_[a-z0-9_]+\.py", name), name
        doc = ast.get_docstring(ast.parse((EXAMPLES / name).read_text(encoding="utf-8")))
        assert doc and "Run: ``python examples/" + name in doc, name


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_example_runs(name: str) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    for pattern in EXPECTED[name]:
        assert re.search(pattern, done.stdout), f"{name}: no {pattern!r} in\n{done.stdout}"

"""``python -m analysis COMMAND``: the study report and general-purpose tools."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from analysis.errors import AnalysisError
from app.errors import AppError
from study.cli.dispatch import dispatch
from study.errors import StudyError

COMMANDS = {
    "report": ("analysis.cli.report", "Write the HTML/Markdown report and results.json."),
    "anova": ("analysis.cli.anova", "Repeated-measures ANOVA on any tidy long-format CSV."),
    "predict": ("analysis.cli.predict", "Run goal predictors over an external trajectory CSV."),
    "power": ("analysis.cli.power", "Power of the paper's hypotheses at several N from a pilot."),
}

EXPECTED = (AnalysisError, StudyError, AppError)
"""The layer's error roots: said on one line (exit 2), never as a traceback."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``python -m analysis`` with ``argv`` (default: the process's arguments)."""
    return dispatch("python -m analysis", __doc__ or "", COMMANDS, argv, expected=EXPECTED)


if __name__ == "__main__":
    sys.exit(main())

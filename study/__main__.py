"""``python -m study COMMAND``: the study server, trials and videos, schedules, headless sessions,
simulation, sweeps, export and salvage."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from app.errors import AppError
from study.cli.dispatch import dispatch
from study.errors import StudyError

COMMANDS = {
    "serve": ("study.cli.serve", "Start the study server (participant + experimenter views)."),
    "trial": ("study.cli.trial", "Run one headless trial and print its outcome as JSON."),
    "render": ("study.cli.render", "Render a trial to MP4 (live or replayed from the store)."),
    "schedule": ("study.cli.schedule", "Print the counterbalanced trial schedule."),
    "run": ("study.cli.run", "Run one whole session headless with a scripted participant."),
    "simulate": ("study.cli.simulate", "Run simulated participants through the whole study."),
    "sweep": ("study.cli.sweep", "Calibrate the arbitration modes by the paper's criteria."),
    "export": ("study.cli.export", "Export a store to tidy CSV + Parquet files with a codebook."),
    "retention": (
        "study.cli.retention",
        "Record a data-retention answer given in person after a session stopped.",
    ),
    "salvage": ("study.cli.salvage", "Copy what is readable of a damaged store into a new one."),
}

EXPECTED = (StudyError, AppError)
"""The layer's error roots: said on one line (exit 2), never as a traceback."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``python -m study`` with ``argv`` (default: the process's arguments)."""
    return dispatch("python -m study", __doc__ or "", COMMANDS, argv, expected=EXPECTED)


if __name__ == "__main__":
    sys.exit(main())

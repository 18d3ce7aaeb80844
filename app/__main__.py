"""``python -m app COMMAND``: run the study server, a headless trial, or render a trial video."""

from __future__ import annotations

import sys

from app.cli import dispatch

COMMANDS = {
    "serve": ("app.ui.serve", "Start the study server (participant + experimenter views)."),
    "trial": ("app.trial.cli", "Run one headless trial and print its outcome as JSON."),
    "render": ("app.trial.render_cli", "Render a trial to MP4 (live or replayed from the store)."),
}

if __name__ == "__main__":
    sys.exit(dispatch("python -m app", __doc__ or "", COMMANDS, None))

"""``python -m analysis COMMAND``: the study report and general-purpose tools."""

from __future__ import annotations

import sys

from study.cli.arguments import dispatch

COMMANDS = {
    "report": ("analysis.cli.report", "Write the HTML/Markdown report and results.json."),
    "anova": ("analysis.cli.anova", "Repeated-measures ANOVA on any tidy long-format CSV."),
    "predict": ("analysis.cli.predict", "Run goal predictors over an external trajectory CSV."),
    "power": ("analysis.cli.power", "Power of the paper's hypotheses at several N from a pilot."),
}

if __name__ == "__main__":
    sys.exit(dispatch("python -m analysis", __doc__ or "", COMMANDS, None))

"""A new report section is one module and one line in ``analysis.sections.SECTIONS``: its text
lands in the report where the line puts it, its rows in the statistics table and results.json."""

from __future__ import annotations

import json
import re
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from analysis import sections
from analysis.load import from_frames
from analysis.render import Section
from analysis.report import write_report
from analysis.sections.context import ReportContext
from analysis.statistics_rows import stat_row
from analysis.study_results import StudyResults
from analysis.synthetic import synthetic_tables


def _runs_section() -> types.ModuleType:
    """A section module written here: a paragraph and one descriptive row."""
    module = types.ModuleType("runs_per_participant")

    def section(ctx: ReportContext) -> Section | None:
        n = ctx.res.cells.groupby("participant").size()
        return Section("Runs per participant", paragraphs=[f"{n.min()} to {n.max()} runs."])

    def rows(res: StudyResults) -> list[dict[str, Any]]:
        n = res.cells.groupby("participant").size()
        return [stat_row("runs", "per_participant", "mean runs", np.nan, None, n.mean(), np.nan)]

    module.section, module.rows = section, rows
    return module


def test_a_section_module_and_one_line_add_text_and_rows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    after = sections.SECTIONS.index(sections.data_quality) + 1
    monkeypatch.setattr(
        sections,
        "SECTIONS",
        (*sections.SECTIONS[:after], _runs_section(), *sections.SECTIONS[after:]),
    )
    t = synthetic_tables(4, seed=4, with_samples=False)
    files = write_report(from_frames(t["trials"], None, t["ratings"], t["events"]), tmp_path)
    heads = re.findall(r"(?m)^## (.+)$", files.markdown.read_text())
    assert heads[heads.index("Data quality per participant") + 1] == "Runs per participant"
    assert "8 to 8 runs." in files.markdown.read_text()
    stats = json.loads(files.results_json.read_text())["statistics"]
    runs = [r for r in stats if r["analysis"] == "runs"]
    assert len(runs) == 1 and runs[0]["statistic"] == 8.0
    assert runs[0]["paper_value"] is None


def test_every_section_module_builds_a_section() -> None:
    for part in sections.SECTIONS:
        assert callable(part.section), part.__name__
        assert part.__doc__, f"{part.__name__} says which section it is"

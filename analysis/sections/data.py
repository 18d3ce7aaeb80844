"""Section "Data": who and what the report covers."""

from __future__ import annotations

import pandas as pd

from analysis.load import StudyTables
from analysis.render import Section, Table
from analysis.sections.context import ReportContext
from analysis.study_results import StudyResults


def section(ctx: ReportContext) -> Section:
    return data_section(ctx.res, ctx.tables, successful_only=ctx.successful_only)


def data_section(res: StudyResults, tables: StudyTables, *, successful_only: bool) -> Section:
    """Who and what the report covers: participants included and left out (and why), runs,
    and which runs the analysed durations include."""
    data = Section("Data")
    data.paragraphs.append(_who(tables) + ".")
    cells = res.cells
    if not cells.empty:
        data.paragraphs.append(_runs(res, successful_only=successful_only))
    trials = tables.trials
    if not trials.empty:
        cols = [c for c in ("phase", "status", "outcome") if c in trials.columns]
        counts = trials.groupby(cols, dropna=False).size().reset_index(name="trials")
        data.tables.append(Table("Trial attempts by phase, status and outcome", counts))
    return data


def _who(tables: StudyTables) -> str:
    """Participants enrolled, included and left out (and why), and sessions under way."""
    trials, excluded = tables.trials, tables.excluded
    enrolled = len(tables.participants) if not tables.participants.empty else None
    with_runs = trials["participant"].nunique() if not trials.empty else 0
    who = f"{with_runs} participant(s) with data"
    if enrolled is not None:
        who = f"{enrolled} participant(s) enrolled, {enrolled - len(excluded)} included"
    if excluded:
        who += "; left out: " + "; ".join(f"{p} ({why})" for p, why in excluded.items())
    p = tables.participants
    if not p.empty and "status" in p.columns:
        under_way = p.loc[p["status"].isin(["enrolled", "running"]), "participant"]
        if len(under_way):
            who += (
                f"; session still under way: {', '.join(map(str, under_way))} (their data as they"
                " stand; a retention question, if the protocol asks one, comes at the end)"
            )
    return who


def _runs(res: StudyResults, *, successful_only: bool) -> str:
    """Participants and analysed runs, and the mean time per task over which runs."""
    cells = res.cells
    n_part = cells["participant"].nunique()
    paper = " (paper: about 28 s)" if res.paper_design else ""
    which = (
        "successful task runs only (--successful-only)"
        if successful_only
        else "all completed task runs, a failed run counting the time until it ended"
    )
    ok = cells[cells["success"].astype(bool)] if "success" in cells.columns else cells
    return (
        f"{n_part} participant(s), {len(cells)} analysed task runs "
        f"({_per_participant(cells)}). Mean time per task over the analysed runs, {which}: "
        f"{cells['duration_s'].mean():.1f} s{paper}; over the successful runs alone: "
        + (f"{ok['duration_s'].mean():.1f} s ({len(ok)} runs)." if len(ok) else "none.")
    )


def _per_participant(cells: pd.DataFrame) -> str:
    n = cells.groupby("participant").size()
    lo, hi = int(n.min()), int(n.max())
    return f"{lo} per participant" if lo == hi else f"{lo} to {hi} per participant"

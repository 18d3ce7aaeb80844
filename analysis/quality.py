"""Data quality per participant: what happened around the runs, before any statistic.

One row per participant from the trials, events and participants tables:

- runs: task runs completed, and how many of them failed; attempts redone, skipped or
  interrupted (a process that stopped mid-run);
- pauses (by the experimenter, or because the participant's tab went away: the ``pause``
  event's ``cause``), reloads (the tab connected again: every ``participant_connected`` after
  the first), disconnections before the session finished, control faults, inputs refused;
- knocks: objects knocked over in any attempt (``analysis.descriptives.knocks_per_trial``);
- attention checks failed of those answered (the participants table);
- whether the participant's data are included, and if not why (data retention).

Headless and simulated sessions have no tab: their pauses, reloads and disconnections are 0.
"""

from __future__ import annotations

import json
from typing import Any

import pandas as pd

from analysis.descriptives import knocks_per_trial
from analysis.load import StudyTables
from analysis.render import Section, Table

COLUMNS = (
    "participant",
    "status",
    "task runs",
    "failed",
    "redone",
    "skipped",
    "interrupted",
    "pauses (experimenter)",
    "pauses (tab away)",
    "reloads",
    "disconnections",
    "faults",
    "inputs refused",
    "knocks",
    "attention checks failed",
    "data",
)


def _detail(value: Any) -> dict[str, Any]:
    if isinstance(value, dict):
        return value
    try:
        out = json.loads(str(value))
    except (TypeError, ValueError):
        return {}
    return out if isinstance(out, dict) else {}


def _event_counts(events: pd.DataFrame) -> pd.DataFrame:
    """Per participant: pauses by cause, reloads, disconnections before the end, faults,
    inputs refused."""
    cols = ["pauses (experimenter)", "pauses (tab away)", "reloads", "disconnections", "faults"]
    cols.append("inputs refused")
    if events.empty or not {"participant", "kind"} <= set(events.columns):
        return pd.DataFrame(columns=cols)
    e = events[events["participant"].notna()].copy()
    e["participant"] = e["participant"].astype(str)
    rows = {}
    for p, g in e.groupby("participant", sort=False):
        kinds = g["kind"].astype(str)
        causes = [_detail(d).get("cause") for d in g.loc[kinds == "pause", "detail"]]
        ended = g.loc[kinds.isin(["finish", "withdraw", "end"]), "at"]
        end = ended.min() if len(ended) else None
        lost = g[(kinds == "participant_disconnected")]
        if end is not None:
            lost = lost[lost["at"] < end]
        rows[p] = {
            "pauses (experimenter)": sum(c != "tab_lost" for c in causes),
            "pauses (tab away)": sum(c == "tab_lost" for c in causes),
            "reloads": max(int((kinds == "participant_connected").sum()) - 1, 0),
            "disconnections": len(lost),
            "faults": int((kinds == "control_fault").sum()),
            "inputs refused": int((kinds == "input_rejected").sum()),
        }
    return pd.DataFrame.from_dict(rows, orient="index", columns=cols)


def data_quality(tables: StudyTables) -> pd.DataFrame:
    """One row per participant (module docstring), excluded participants last."""
    t = tables.trials
    t = (
        t.assign(knocks=t["trial_id"].map(knocks_per_trial(t, tables.samples)).fillna(0))
        if ("trial_id" in t.columns)
        else t.assign(knocks=0)
    )
    task = t[t["phase"] == "task"]
    done = task[task["status"] == "completed"]
    ok = done["success"].astype(bool) if "success" in done.columns else done["outcome"] == "success"
    by = t.groupby("participant")
    out = pd.DataFrame(
        {
            "task runs": done.groupby("participant").size(),
            "failed": done[~ok].groupby("participant").size(),
            "redone": t[t["status"] == "redone"].groupby("participant").size(),
            "skipped": t[t["status"] == "skipped"].groupby("participant").size(),
            "interrupted": t[t["status"] == "interrupted"].groupby("participant").size(),
            "knocks": by["knocks"].sum(),
        }
    )
    out = out.join(_event_counts(tables.events), how="outer")
    p = tables.participants
    if not p.empty and "participant" in p.columns:
        p = p.assign(participant=p["participant"].astype(str)).set_index("participant")
        out = out.reindex(list(dict.fromkeys([*out.index, *p.index])))
        out["status"] = p["status"] if "status" in p.columns else ""
        if {"attention_checks", "attention_failures"} <= set(p.columns):
            out["attention checks failed"] = [
                f"{_int(p.at[i, 'attention_failures'])} of {_int(p.at[i, 'attention_checks'])}"
                if i in p.index and pd.notna(p.at[i, "attention_checks"])
                else ""
                for i in out.index
            ]
        included = (
            p["included"].astype(str).str.lower().isin(["true", "1"]) if "included" in p else None
        )
        out["data"] = [
            "included"
            if included is None or i not in p.index or included[i]
            else f"left out: {p.at[i, 'excluded_because']}"
            for i in out.index
        ]
    for c in COLUMNS[1:]:
        if c not in out.columns:
            out[c] = "" if c in ("status", "attention checks failed", "data") else 0
    counts = [c for c in COLUMNS[2:-2] if c != "attention checks failed"]
    excluded = out["data"].astype(str).str.startswith("left out")
    out[counts] = out[counts].astype("Float64").fillna(0).astype("Int64").astype(object)
    out.loc[excluded, counts] = ""
    out = out.rename_axis("participant").reset_index()
    out["_x"] = excluded.to_numpy()
    return (
        out.sort_values(["_x", "participant"])
        .drop(columns="_x")[list(COLUMNS)]
        .reset_index(drop=True)
    )


def _int(v: Any) -> int:
    return 0 if v is None or pd.isna(v) else int(v)


def quality_section(tables: StudyTables) -> Section:
    """The report's data-quality listing."""
    sec = Section("Data quality per participant")
    q = data_quality(tables)
    sec.paragraphs.append(
        "What happened around each participant's runs: task runs completed and failed, "
        "attempts redone, skipped or interrupted; pauses by the experimenter or because the "
        "page went away, reloads of the page, disconnections before the end, control faults, "
        "inputs the server refused; objects knocked over in any attempt; attention checks "
        "failed. A participant left out (data retention) has no data beyond the reason."
    )
    sec.tables.append(Table("Per participant", q))
    return sec


__all__ = ["data_quality", "quality_section"]

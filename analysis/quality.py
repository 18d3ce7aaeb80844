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
from analysis.load import StudyTables, as_bool
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
    except json.JSONDecodeError:  # a detail that is not JSON (hand-made tables): no fields
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


COUNTS = [c for c in COLUMNS[2:-2]]
"""The columns that count something (blank for a participant left out)."""


def _run_counts(tables: StudyTables) -> pd.DataFrame:
    """Per participant: task runs completed and failed; attempts redone, skipped,
    interrupted; knocks in any attempt."""
    t = tables.trials
    knocks = t["trial_id"].map(knocks_per_trial(t, tables.samples)) if "trial_id" in t else 0
    t = t.assign(knocks=pd.Series(knocks, index=t.index).fillna(0))
    done = t[(t["phase"] == "task") & (t["status"] == "completed")]
    ok = as_bool(done["success"]) if "success" in done else done["outcome"].eq("success")

    def per(rows: pd.DataFrame) -> pd.Series:
        return rows.groupby("participant").size()

    return pd.DataFrame(
        {
            "task runs": per(done),
            "failed": per(done[~ok]),
            **{s: per(t[t["status"] == s]) for s in ("redone", "skipped", "interrupted")},
            "knocks": t.groupby("participant")["knocks"].sum(),
        }
    )


def _from_participants(p: pd.DataFrame, index: pd.Index) -> pd.DataFrame:
    """Status, attention checks failed and whether the data are included, from the export's
    participants table (all blank without one)."""
    out = pd.DataFrame(index=index, columns=["status", "attention checks failed", "data"])
    out[:] = ""
    out["data"] = "included"
    if p.empty or "participant" not in p.columns:
        return out
    p = p.assign(participant=p["participant"].astype(str)).set_index("participant")
    p = p.reindex(index)
    if "status" in p:
        out["status"] = p["status"].fillna("")
    if {"attention_checks", "attention_failures"} <= set(p.columns):
        asked = pd.to_numeric(p["attention_checks"], errors="coerce")
        failed = pd.to_numeric(p["attention_failures"], errors="coerce").fillna(0)
        out["attention checks failed"] = [
            f"{int(f)} of {int(a)}" if pd.notna(a) else ""
            for f, a in zip(failed, asked, strict=True)
        ]
    if "included" in p:
        kept = as_bool(p["included"].fillna(True))
        why = p.get("excluded_because", "")
        out.loc[~kept, "data"] = "left out: " + pd.Series(why, index=index)[~kept].astype(str)
    return out


def data_quality(tables: StudyTables) -> pd.DataFrame:
    """One row per participant (module docstring), those left out last."""
    out = _run_counts(tables).join(_event_counts(tables.events), how="outer")
    p = tables.participants
    listed = p["participant"].astype(str) if "participant" in p.columns else []
    index = pd.Index(list(dict.fromkeys([*out.index, *listed])), name="participant")
    out = out.reindex(index)
    for c in COUNTS:
        if c not in out.columns:
            out[c] = 0
    out[COUNTS] = out[COUNTS].astype("Float64").fillna(0).astype("Int64").astype(object)
    out = out.join(_from_participants(p, index))
    left_out = out["data"].str.startswith("left out")
    out.loc[left_out, COUNTS] = ""
    out = out.assign(_left_out=left_out).reset_index()
    out = out.sort_values(["_left_out", "participant"], kind="stable")
    return out[list(COLUMNS)].reset_index(drop=True)


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

"""Descriptives first: per condition how many, how fast, how often successful, how many knocks,
how many runs timed out.

For every task and mode (and the unassisted practice runs) over the completed attempts:
participants, runs, successes and the success rate; time to complete as mean, SD and median,
twice -- over the successful runs only, and over all completed runs, where a failed run counts
with the time until it ended (a timeout counts the whole limit); objects knocked over; and the
failed runs by how they ended (timeouts, and the rest by outcome).

Knocks come from the trials table's ``knocks`` column when the data have one, else from the
samples: each ``knocked_over:<object>`` trial event (``app.trial.events``) is one knock.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.load import StudyTables
from analysis.render import Section, Table, fmt

KNOCK_EVENT = '"knocked_over:'
"""How a knock looks in a sample's ``events`` (a JSON list of event strings)."""
MISSING = "–"
"""Shown for a value that is not defined (an SD of one run, a median of none)."""
PRACTICE = "practice"
TIMEOUT = "timeout"


def knocks_per_trial(trials: pd.DataFrame, samples: pd.DataFrame | None) -> pd.Series:
    """Objects knocked over per trial attempt, indexed by ``trial_id`` (0 where none)."""
    if "trial_id" not in trials.columns:
        return pd.Series(dtype=float)
    ids = trials["trial_id"]
    if "knocks" in trials.columns:
        return pd.Series(
            pd.to_numeric(trials["knocks"], errors="coerce").fillna(0).to_numpy(), index=ids
        )
    counts = pd.Series(0, index=ids, dtype=float)
    if samples is None or samples.empty or "events" not in samples.columns:
        return counts
    events = samples["events"].astype(str)
    hits = events.str.count(KNOCK_EVENT)
    per = hits[hits > 0].groupby(samples.loc[hits > 0, "trial_id"]).sum()
    counts.update(per.astype(float))
    return counts


def _stats(values: pd.Series) -> dict[str, float]:
    v = pd.to_numeric(values, errors="coerce").dropna()
    return {
        "n": len(v),
        "mean": float(v.mean()) if len(v) else np.nan,
        "sd": float(v.std(ddof=1)) if len(v) > 1 else np.nan,
        "median": float(v.median()) if len(v) else np.nan,
    }


def condition_descriptives(
    tables: StudyTables, *, modes: Sequence[str] | None = None, split: Sequence[str] = ()
) -> pd.DataFrame:
    """One row per condition (practice first, then task by task in ``modes``' order):
    ``task``, ``mode``, each factor of ``split`` (other factors the protocol declares: a
    condition is a task, a mode and a level of each), ``participants``, ``runs``, ``successes``, ``success_rate``,
    ``time_ok_{n,mean,sd,median}`` (successful runs), ``time_all_{mean,sd,median}`` (all
    completed runs), ``knocks``, ``knocks_per_run``, ``timeouts`` and ``other_failures`` (the
    failed runs that did not time out, as ``{outcome: runs}``)."""
    t = tables.trials
    done = t[t["status"] == "completed"].copy()
    if done.empty:
        return pd.DataFrame()
    done["knocks"] = done["trial_id"].map(knocks_per_trial(t, tables.samples)).fillna(0)
    done["ok"] = (
        done["success"].astype(bool) if "success" in done.columns else done["outcome"].eq("success")
    )
    done["outcome_"] = (
        done["outcome"].astype(str)
        if "outcome" in done.columns
        else np.where(done["ok"], "success", "failed")
    )
    done["task"] = np.where(done["phase"] == "training", PRACTICE, done["task"])
    present = list(dict.fromkeys(done.loc[done["phase"] == "task", "mode"]))
    order = [m for m in (modes or ()) if m in present] + [
        m for m in present if m not in (modes or ())
    ]
    rank = {m: i for i, m in enumerate(order)}
    split = [f for f in split if f in done.columns]
    rows = []
    for key, g in done.groupby(["task", "mode", *split], sort=False, dropna=False):
        task, mode, *levels = key
        ok, every = _stats(g.loc[g["ok"], "duration_s"]), _stats(g["duration_s"])
        failed = g.loc[~g["ok"], "outcome_"]
        rows.append(
            {
                "task": task,
                "mode": mode,
                **{f: "" if pd.isna(v) else v for f, v in zip(split, levels, strict=True)},
                "participants": g["participant"].nunique(),
                "runs": len(g),
                "successes": int(g["ok"].sum()),
                "success_rate": float(g["ok"].mean()),
                "time_ok_n": ok["n"],
                "time_ok_mean": ok["mean"],
                "time_ok_sd": ok["sd"],
                "time_ok_median": ok["median"],
                "time_all_mean": every["mean"],
                "time_all_sd": every["sd"],
                "time_all_median": every["median"],
                "knocks": int(g["knocks"].sum()),
                "knocks_per_run": float(g["knocks"].mean()),
                "timeouts": int(failed.eq(TIMEOUT).sum()),
                "other_failures": failed[failed.ne(TIMEOUT)].value_counts().sort_index().to_dict(),
            }
        )
    out = pd.DataFrame(rows)
    out["_practice"] = out["task"] != PRACTICE
    out["_mode"] = out["mode"].map(rank).fillna(-1)
    out = out.sort_values(["_practice", "task", "_mode", *split], kind="stable")
    out = out.drop(columns=["_practice", "_mode"])
    return out.reset_index(drop=True)


def show(x: float, digits: int = 1) -> str:
    """``fmt`` with :data:`MISSING` for a value that is not defined."""
    return MISSING if x is None or pd.isna(x) else fmt(x, digits)


def descriptive_section(
    tables: StudyTables, *, modes: Sequence[str] | None = None, split: Sequence[str] = ()
) -> Section:
    """The report's descriptives by condition (module docstring); ``split``: the protocol's
    factors besides task and mode, a column each."""
    sec = Section("Descriptives by condition")
    d = condition_descriptives(tables, modes=modes, split=split)
    if d.empty:
        sec.paragraphs.append("No completed runs yet: nothing to describe.")
        return sec
    sec.paragraphs.append(
        "Every completed run, by condition (practice: the unassisted runs before the tasks). "
        "Time to complete is given twice: over the successful runs only (the time it took to "
        "lift the target), and over all completed runs, where a failed run counts with the time "
        "until it ended (a timeout with the whole time limit) -- the durations the timing "
        f"analyses below use unless run with --successful-only. {MISSING}: not defined (an SD "
        "needs two runs, a mean one)."
    )
    frame = pd.DataFrame(
        {
            "task": d["task"],
            "mode": d["mode"],
            **{f: d[f] for f in split if f in d.columns},
            "n (participants)": d["participants"],
            "runs": d["runs"],
            "success": [f"{r.successes}/{r.runs} ({r.success_rate:.0%})" for r in d.itertuples()],
            "time of successful runs: mean (SD)": [
                f"{show(r.time_ok_mean)} ({show(r.time_ok_sd)})" for r in d.itertuples()
            ],
            "their median": d["time_ok_median"].map(show),
            "time of all completed runs: mean (SD)": [
                f"{show(r.time_all_mean)} ({show(r.time_all_sd)})" for r in d.itertuples()
            ],
            "all: median": d["time_all_median"].map(show),
            "knocks (per run)": [f"{r.knocks} ({r.knocks_per_run:.2f})" for r in d.itertuples()],
            "timeouts": d["timeouts"],
            "other failures": d["other_failures"].map(_failures),
        }
    )
    sec.tables.append(
        Table(
            "Runs, success, time (s), knocks and timeouts per condition",
            frame,
            "Knocks: objects knocked over (trial events knocked_over), all completed runs. "
            "Timeouts: runs that reached the time limit; other failures: the other failed runs "
            "by outcome.",
        )
    )
    return sec


def _failures(counts: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in counts.items()) or "0"


__all__ = ["condition_descriptives", "descriptive_section", "knocks_per_trial"]

"""How long the robot predicts the decoy in each Wrong trial (is the Wrong condition wrong?).

For a completed task trial with correctness ``wrong``, the decoy share is the fraction of its
duration during which the robot's predicted goal is not the participant's target,

    share = (1 / T) * sum over ticks of dt [predicted(t) != target],

read from the logged samples (every tick lasts ``dt``, so it is the share of the trial's ticks).
The paper built its Wrong tasks so that amnesic prediction "guarantees wrong prediction until
the user makes his preference clear"; a share near 0 means the manipulation hardly bites.
``decoy_section`` is the report's paragraph and table (median over trials, by task and mode).
"""

from __future__ import annotations

import pandas as pd

from analysis.load import StudyTables
from analysis.render import Section, Table, fmt

WRONG = "wrong"


def decoy_shares(trials: pd.DataFrame, samples: pd.DataFrame) -> pd.DataFrame:
    """One row per completed Wrong task trial: ``participant, task, mode, duration_s,
    decoy_share`` (empty when the tables hold none or have no samples)."""
    columns = ["trial_id", "participant", "task", "mode", "duration_s", "decoy_share"]
    need = {"trial_id", "correctness", "phase", "status", "target"}
    if samples is None or samples.empty or not need <= set(trials.columns):
        return pd.DataFrame(columns=columns)
    wrong = trials[
        (trials["phase"] == "task")
        & (trials["status"] == "completed")
        & (trials["correctness"] == WRONG)
    ]
    if wrong.empty:
        return pd.DataFrame(columns=columns)
    s = samples[samples["trial_id"].isin(wrong["trial_id"])][["trial_id", "predicted"]]
    target = s["trial_id"].map(wrong.set_index("trial_id")["target"])
    decoy = (s["predicted"].astype(str) != target.astype(str)).groupby(s["trial_id"]).mean()
    out = wrong[["trial_id", "participant", "task", "mode", "duration_s"]].copy()
    out["decoy_share"] = out["trial_id"].map(decoy)
    return out.dropna(subset=["decoy_share"]).reset_index(drop=True)[columns]


def decoy_section(tables: StudyTables) -> Section | None:
    """The report's section: median decoy share over Wrong trials, then by task and mode."""
    shares = decoy_shares(tables.trials, tables.samples)
    if shares.empty:
        return None
    median = float(shares["decoy_share"].median())
    sec = Section("Wrong prediction: how long the robot predicts the decoy")
    sec.paragraphs.append(
        f"Share of each Wrong trial's duration during which the robot predicts an object other "
        f"than the target: median {median:.2f} over {len(shares)} trials (interquartile range "
        f"{shares['decoy_share'].quantile(0.25):.2f}-{shares['decoy_share'].quantile(0.75):.2f}). "
        "The paper's Wrong condition keeps the prediction wrong until the user's input is "
        "nearer the target."
    )
    by = shares.groupby(["task", "mode"])
    table = pd.DataFrame(
        {
            "median share": by["decoy_share"].median().map(fmt),
            "mean duration (s)": by["duration_s"].mean().map(fmt),
            "trials": by.size(),
        }
    ).reset_index()
    sec.tables.append(Table("Decoy share by task and mode", table))
    return sec

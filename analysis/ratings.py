"""Ratings by condition (the paper's Fig. 8): every rated item, per task and mode.

From the tidy ``ratings`` table: the items asked after each assisted run (``phase`` task, a
``mode``) summarised per task and mode -- n, mean, SD, median, SE -- beside the same items
asked after the practice runs (the robot without assistance: the baseline), and the preference
between a task's two runs per task, re-centred on the reference mode (the export's
``<item>_<mode>`` column of the trials table: positive = preferred that mode's run).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.descriptives import MISSING, show
from analysis.load import StudyTables
from analysis.render import Section, Table


def _mode(ratings: pd.DataFrame) -> pd.Series:
    return ratings["mode"].astype("string").fillna("").astype(str)


def _summary(values: pd.Series) -> dict[str, float]:
    v = pd.to_numeric(values, errors="coerce").dropna()
    n = len(v)
    sd = float(v.std(ddof=1)) if n > 1 else np.nan
    return {
        "n": n,
        "mean": float(v.mean()) if n else np.nan,
        "sd": sd,
        "median": float(v.median()) if n else np.nan,
        "se": sd / np.sqrt(n) if n > 1 else np.nan,
    }


def rating_summary(ratings: pd.DataFrame, *, modes: Sequence[str] | None = None) -> pd.DataFrame:
    """Per item, task and mode of the per-run ratings: ``n``, ``mean``, ``sd``, ``median``,
    ``se`` (items in the order asked, tasks sorted, modes in ``modes``' order)."""
    need = {"phase", "task", "mode", "item", "value"}
    if ratings.empty or not need <= set(ratings.columns):
        return pd.DataFrame()
    r = ratings[(ratings["phase"] == "task") & (_mode(ratings) != "")]
    if r.empty:
        return pd.DataFrame()
    present = list(dict.fromkeys(r["mode"]))
    order = [m for m in (modes or ()) if m in present] + [
        m for m in present if m not in (modes or ())
    ]
    rows = [
        {"item": item, "task": task, "mode": mode, **_summary(g["value"])}
        for (item, task, mode), g in r.groupby(["item", "task", "mode"], sort=False)
    ]
    out = pd.DataFrame(rows)
    items = {i: k for k, i in enumerate(dict.fromkeys(r["item"]))}
    out["_i"], out["_m"] = (
        out["item"].map(items),
        out["mode"].map({m: k for k, m in enumerate(order)}),
    )
    return out.sort_values(["_i", "task", "_m"]).drop(columns=["_i", "_m"]).reset_index(drop=True)


def baseline_summary(ratings: pd.DataFrame) -> pd.DataFrame:
    """The items asked after the practice runs: ``item``, ``n``, ``mean``, ``sd``, ``median``."""
    if ratings.empty or "phase" not in ratings.columns:
        return pd.DataFrame()
    r = ratings[ratings["phase"] == "training"]
    rows = [{"item": i, **_summary(g["value"])} for i, g in r.groupby("item", sort=False)]
    return pd.DataFrame(rows)


def preference_summary(tables: StudyTables) -> tuple[pd.DataFrame, str | None]:
    """Per task, the preference re-centred on the reference mode (``n``, ``mean``, ``sd``,
    ``median``, ``se``), and that mode (``None`` when the data have no such column)."""
    r, t = tables.ratings, tables.trials
    if r.empty or not {"phase", "mode", "item"} <= set(r.columns):
        return pd.DataFrame(), None
    items = list(dict.fromkeys(r.loc[(r["phase"] == "task") & (_mode(r) == ""), "item"]))
    for item in items:
        columns = [c for c in t.columns if c.startswith(f"{item}_")]
        if not columns:
            continue
        column = columns[0]
        per = (
            t[t["phase"] == "task"]
            .assign(v=pd.to_numeric(t[column], errors="coerce"))
            .groupby(["participant", "task"])["v"]
            .first()
            .dropna()
            .reset_index()
        )
        rows = [{"task": k, **_summary(g["v"])} for k, g in per.groupby("task", sort=True)]
        return pd.DataFrame(rows), column.removeprefix(f"{item}_")
    return pd.DataFrame(), None


def _cell(row: pd.Series | object) -> str:
    mean, sd = row.mean, row.sd
    return f"{show(mean, 2)} ({show(sd, 2)})"


def ratings_section(
    tables: StudyTables,
    *,
    modes: Sequence[str] | None = None,
    figures: Sequence[object] = (),
) -> Section | None:
    """The report's ratings by condition (``None`` when the data have no ratings)."""
    summary = rating_summary(tables.ratings, modes=modes)
    baseline = baseline_summary(tables.ratings)
    pref, reference = preference_summary(tables)
    if summary.empty and baseline.empty and pref.empty:
        return None
    sec = Section("Ratings by condition (Fig. 8)")
    sec.paragraphs.append(
        "Every rated item, per task and mode: mean (SD), median and n (one answer per "
        "participant and run); after the practice runs, the same items about the robot "
        "without assistance (the baseline). Ratings are on the protocol's scale (1 = its first "
        f"anchor). {MISSING}: not defined (an SD needs two answers)."
    )
    if not summary.empty:
        wide = summary.assign(cell=[_cell(r) for r in summary.itertuples()])
        frame = wide.pivot_table(
            index=["task", "mode"], columns="item", values="cell", aggfunc="first", sort=False
        )
        frame = frame[list(dict.fromkeys(summary["item"]))]
        medians = summary.pivot_table(
            index=["task", "mode"], columns="item", values="median", aggfunc="first", sort=False
        )
        for item in frame.columns:
            frame[f"{item} median"] = medians[item].map(lambda v: show(v, 1))
        n = summary.groupby(["task", "mode"], sort=False)["n"].max()
        frame["n"] = n
        order = summary[["task", "mode"]].drop_duplicates()
        frame = frame.reindex(pd.MultiIndex.from_frame(order)).reset_index()
        sec.tables.append(Table("Ratings after each run: mean (SD), median", frame))
    if not baseline.empty:
        sec.tables.append(
            Table(
                "Ratings after the practice runs (no assistance): mean (SD), median",
                pd.DataFrame(
                    {
                        "item": baseline["item"],
                        "mean (SD)": [_cell(r) for r in baseline.itertuples()],
                        "median": baseline["median"].map(lambda v: show(v, 1)),
                        "n": baseline["n"],
                    }
                ),
            )
        )
    if not pref.empty:
        sec.tables.append(
            Table(
                f"Preference between a task's two runs, re-centred on {reference}",
                pd.DataFrame(
                    {
                        "task": pref["task"],
                        "mean (SD)": [_cell(r) for r in pref.itertuples()],
                        "median": pref["median"].map(lambda v: show(v, 1)),
                        "n": pref["n"],
                    }
                ),
                f"Positive: preferred the {reference} run; negative: the other run; 0: no "
                "preference.",
            )
        )
    sec.figures += list(figures)  # type: ignore[arg-type]
    return sec


__all__ = ["baseline_summary", "preference_summary", "rating_summary", "ratings_section"]

"""Contacts as a dependent measure beside time: how often, and how hard, the arm hit objects.

The export's ``trials`` table carries per trial ``contacts`` (touches of the wrist, hand or
fingers on an object, a grasp's own finger contacts excluded) and ``contact_impulse_ns`` (their
total normal impulse, N s); see ``app.trial.contacts``. ``contact_section`` summarises them by
task and mode over completed task trials -- means, the objects knocked over per trial (the
export's ``knocks``: stood up again under ``on_knock = "reset"``), and how many trials ended
because of an accident (only under ``on_knock = "end"``) -- for the report.
"""

from __future__ import annotations

import pandas as pd

from analysis.load import StudyTables
from analysis.render import Section, Table, fmt

FAILED_BY_CONTACT = ("dropped", "knocked_over", "pushed_off")


def contact_summary(trials: pd.DataFrame) -> pd.DataFrame:
    """Per task and mode: ``trials``, ``mean touches``, ``mean impulse (N s)``, ``mean knocks``
    (when the export has them) and the number of trials that ended ``dropped``,
    ``knocked_over`` or ``pushed_off`` (empty without the columns)."""
    need = {"contacts", "contact_impulse_ns", "task", "mode", "phase", "status", "outcome"}
    if not need <= set(trials.columns):
        return pd.DataFrame()
    done = trials[(trials["phase"] == "task") & (trials["status"] == "completed")]
    if done.empty:
        return pd.DataFrame()
    by = done.groupby(["task", "mode"])
    columns = {
        "trials": by.size(),
        "mean touches": by["contacts"].mean().astype(float),
        "mean impulse (N s)": by["contact_impulse_ns"].mean().astype(float),
    }
    if "knocks" in done:
        columns["mean knocks"] = by["knocks"].mean().astype(float)
    columns["ended by an accident"] = by["outcome"].agg(
        lambda o: int(o.isin(FAILED_BY_CONTACT).sum())
    )
    return pd.DataFrame(columns).reset_index()


def contact_section(tables: StudyTables) -> Section | None:
    """The report's section on contacts (``None`` when the data have no contact columns)."""
    summary = contact_summary(tables.trials)
    if summary.empty:
        return None
    sec = Section("Contacts: the arm touching objects")
    sec.paragraphs.append(
        "Touches of the wrist, hand or fingers on an object per trial (the fingers closing in a "
        "grasp do not count) and their normal impulse; objects knocked over per trial; trials "
        "that ended with a held object dropped, an object knocked over or one pushed off the "
        "table (under on_knock = reset none does: the object is stood up again)."
    )
    shown = summary.copy()
    for col in ("mean touches", "mean impulse (N s)", "mean knocks"):
        if col in shown:
            shown[col] = shown[col].map(fmt)
    sec.tables.append(Table("Contacts by task and mode", shown))
    return sec

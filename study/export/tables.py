"""Tidy long-format tables from a study store: trials, samples, ratings, answers,
participants, events, sessions.

``tidy_tables(store_or_path)`` is the one place that defines them (the team contract's "Tidy
tables"); ``python -m study export`` writes them as CSV and Parquet with a codebook
(``study.codebook`` describes every column). The store is opened read-only and never written.

Data retention is honoured here (``study.retention``): when the protocol asks the end-of-study
retention question, a participant who did not agree to keep their data -- declined, or whose
session is over without an answer (withdrew, ended early) -- has no row in any table but
``participants``, which says why (``included`` false, ``excluded_because``). A session still
under way is exported as it stands (``metadata.json``: ``retention_pending``).

The questionnaire layout comes from the protocol the store was run with: the text the store
keeps (``study.protocol.protocol_from_store``), else a matching protocol file, else it is
inferred from the data (``resolve_protocol``). A trial left ``running`` by a dead process is
exported as ``interrupted`` (``study.store.orphans``).

Derived columns of ``trials``:
    training_time_s   mean ``duration_s`` of the participant's completed training runs
    baseline_rating   mean of the participant's after-training ratings (all items)
    tasks_completed   task trials with status "completed" that started before this one
    <item>            per-condition Likert answer about this trial (after_run items)
    preference        the raw answer to the task's preference item, on every run of the task
    preference_<m>    the same re-centred on the mode ``m`` (the protocol's last mode, e.g.
                      aggressive): ``value - mid`` if ``m`` was the second run, ``mid - value``
                      if it was the first, ``mid = (points + 1) / 2``; positive = preferred m
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from app.trial.accidents import ACCIDENT_MEASURES, accident_totals
from app.trial.contacts import contact_totals
from app.trial.events import TrialEvent, decode_events
from app.trial.samples import SAMPLE_COLUMNS
from study.protocol import (
    TRAINING_MODE,
    AttentionItem,
    ChoiceItem,
)
from study.retention import retention_decisions
from study.store import Store

if TYPE_CHECKING:
    from study.protocol import Protocol
from study.export.columns import (
    ANSWER_COLUMNS,
    DEFAULT_POINTS,
    EVENT_COLUMNS,
    PARTICIPANT_COLUMNS,
    RATING_COLUMNS,
    RECRUITMENT_COLUMNS,
    SAMPLE_KEY,
    SESSION_COLUMNS,
    participant_item_column,
    trial_columns,
)
from study.export.errors import ExportError
from study.export.source import resolve_protocol


def tidy_tables(
    store_or_path: Store | str | os.PathLike[str],
    *,
    protocol: Protocol | None = None,
    search: Sequence[Path] | None = None,
) -> dict[str, pd.DataFrame]:
    """The tidy tables of a store: ``{"trials", "samples", "ratings", "answers",
    "participants", "events", "sessions"}`` (module docstring: who is left out).

    ``protocol`` (optional; must be the one the store was run with) names the questionnaire's
    items and scales; without it ``resolve_protocol(store, search=search)`` picks one.
    """
    if isinstance(store_or_path, Store):
        return _Exporter(store_or_path, protocol, search).tables()
    with Store.open_readonly(store_or_path) as store:
        return _Exporter(store, protocol, search).tables()


class _Exporter:
    def __init__(
        self, store: Store, protocol: Protocol | None, search: Sequence[Path] | None
    ) -> None:
        self.store = store
        if protocol is None:
            protocol, _ = resolve_protocol(store, search=search)
        elif protocol.content_hash != store.meta.protocol_hash:
            raise ExportError(
                f"{store.path} was written by protocol {store.meta.protocol_id!r} (hash"
                f" {store.meta.protocol_hash[:12]}), not by {protocol.path} (hash"
                f" {protocol.content_hash[:12]}); pass the protocol the study ran with, or none"
                " to use the one the store keeps"
            )
        self.protocol = protocol
        self.retention = retention_decisions(store, protocol)
        keep = self.retention.kept

        def kept(df: pd.DataFrame) -> pd.DataFrame:
            return df[df["participant"].isin(keep)]

        self.raw_trials = kept(store.frame("trials")).sort_values("trial_id", kind="stable")
        self.raw_ratings = kept(store.frame("ratings")).sort_values("rating_id", kind="stable")
        self.raw_answers = kept(store.frame("answers")).sort_values("answer_id", kind="stable")
        self.all_participants = store.frame("participants")
        self.participants = kept(self.all_participants)
        self.assignments = kept(store.frame("assignments"))

    # -- questionnaire layout ---------------------------------------------------------------
    def _items(self) -> tuple[list[str], list[str], float, str | None]:
        """(after_run item ids, after_task item ids, scale midpoint, reference mode)."""
        if self.protocol is not None:
            q = self.protocol.questionnaire
            modes = self.protocol.mode_names
            after_task = [i.id for i in q.after_task]
            mid = q.after_task[0].scale.midpoint if q.after_task else (q.points + 1) / 2
            return [i.id for i in q.after_run], after_task, mid, modes[-1]
        r = self.raw_ratings
        task_rows = r[r["phase"] == "task"]
        after_run = list(dict.fromkeys(task_rows.loc[task_rows["mode"].notna(), "item"]))
        after_task = list(dict.fromkeys(task_rows.loc[task_rows["mode"].isna(), "item"]))
        t = self.raw_trials
        modes = sorted(set(t.loc[t["phase"] == "task", "mode"].dropna()))
        reference = None
        if len(modes) == 2:
            reference = "aggressive" if "aggressive" in modes else modes[-1]
        return after_run, after_task, (DEFAULT_POINTS + 1) / 2, reference

    def tables(self) -> dict[str, pd.DataFrame]:
        samples = self.samples()
        answers = self.answers()
        return {
            "trials": self.trials(samples),
            "samples": samples,
            "ratings": self.ratings(),
            "answers": answers,
            "participants": self.participant_table(answers),
            "events": self.events(),
            "sessions": self.sessions(),
        }

    # -- trials ------------------------------------------------------------------------------
    def trials(self, samples: pd.DataFrame | None = None) -> pd.DataFrame:
        t = self.raw_trials.copy()
        t = _with_event_totals(t, self.store.samples() if samples is None else samples)
        rows = self.participants.set_index("participant")["schedule_row"]
        t["schedule_row"] = t["participant"].map(rows)
        t["mode"] = t["mode"].where(t["phase"] != "training", TRAINING_MODE)
        t = self._factor_levels(t)
        t["success"] = t["success"].map(lambda v: pd.NA if pd.isna(v) else bool(v))
        t = self._covariates(t)
        after_run, after_task, mid, reference = self._items()
        t = self._condition_ratings(t, after_run)
        t = self._preferences(t, after_task, mid, reference)
        extra = [*after_run]
        for item in after_task:
            extra.append(item)
            if reference is not None:
                extra.append(f"{item}_{reference}")
        factors = None if self.protocol is None else tuple(self.protocol.factors)
        out = t[[*trial_columns(factors), *extra, "trial_id"]].reset_index(drop=True)
        return _typed(
            out,
            ints=(
                "session_id",
                "schedule_row",
                "position",
                "attempt",
                "ticks",
                "contacts",
                *ACCIDENT_MEASURES,
                "tasks_completed",
                "trial_id",
                *after_run,
                *after_task,
            ),
            bools=("success",),
        )

    def _factor_levels(self, t: pd.DataFrame) -> pd.DataFrame:
        """One column per declared factor: the trial's level (``Protocol.levels``); a training
        run has the participant's between levels, ``mode`` = ``none`` and no other level."""
        if self.protocol is None:
            return t
        protocol = self.protocol
        names = tuple(protocol.factors)
        levels = [
            protocol.levels(None if phase == "training" else task, mode, row=int(row))
            for phase, task, mode, row in zip(
                t["phase"], t["task"], t["mode"], t["schedule_row"], strict=True
            )
        ]
        for name in names:
            column = [lv.get(name) for lv in levels]
            if name == "mode":
                column = [TRAINING_MODE if v is None else v for v in column]
            t[name] = pd.Series(column, index=t.index, dtype="str")
        return t

    def _covariates(self, t: pd.DataFrame) -> pd.DataFrame:
        training = t[(t["phase"] == "training") & (t["status"] == "completed")]
        t["training_time_s"] = t["participant"].map(
            training.groupby("participant")["duration_s"].mean()
        )
        r = self.raw_ratings
        baseline = r[r["phase"] == "training"].groupby("participant")["value"].mean()
        t["baseline_rating"] = t["participant"].map(baseline)
        done = ((t["phase"] == "task") & (t["status"] == "completed")).astype(int)
        # completed task trials strictly before each trial, per participant (trial_id order)
        t["tasks_completed"] = done.groupby(t["participant"]).cumsum() - done
        return t

    def _condition_ratings(self, t: pd.DataFrame, items: list[str]) -> pd.DataFrame:
        """Each after-run answer on the trial it rates: the rating's ``trial_id``, or for a
        rating without one, the completed trial of its participant, task, mode and run. A later
        answer replaces an earlier one."""
        for item in items:
            t[item] = pd.Series(pd.NA, index=t.index, dtype="object")
        r = self.raw_ratings
        for row in r[(r["phase"] == "task") & r["item"].isin(items)].itertuples(index=False):
            if pd.notna(row.trial_id):
                rated = t["trial_id"] == row.trial_id
            else:
                rated = (
                    (t["participant"] == row.participant)
                    & (t["task"] == row.task)
                    & (t["mode"] == row.mode)
                    & (t["run"] == row.run)
                    & (t["status"] == "completed")
                )
            t.loc[rated, row.item] = row.value
        return t

    def _preferences(
        self, t: pd.DataFrame, items: list[str], mid: float, reference: str | None
    ) -> pd.DataFrame:
        """The after-task answer on every run of its task, raw and re-centred on ``reference``
        (``value - mid`` if the reference mode was the second run, ``mid - value`` if first)."""
        a = self.assignments
        run_of = {
            (p, k, m): run
            for p, k, m, run in a[["participant", "task", "mode", "run"]].itertuples(index=False)
        }
        for item in items:
            t[item] = pd.Series(pd.NA, index=t.index, dtype="object")
            if reference is not None:
                t[f"{item}_{reference}"] = np.nan
        r = self.raw_ratings
        for row in r[(r["phase"] == "task") & r["item"].isin(items)].itertuples(index=False):
            runs = (
                (t["participant"] == row.participant)
                & (t["task"] == row.task)
                & (t["phase"] == "task")
            )
            t.loc[runs, row.item] = row.value
            if reference is None:
                continue
            run = run_of.get((row.participant, row.task, reference))
            centred = {"second": row.value - mid, "first": mid - row.value}.get(run, np.nan)
            t.loc[runs, f"{row.item}_{reference}"] = centred
        return t

    # -- samples -----------------------------------------------------------------------------
    def samples(self) -> pd.DataFrame:
        s = self.store.samples()
        s = s[s["trial_id"].isin(self.raw_trials["trial_id"])]
        t = self.raw_trials.set_index("trial_id")
        names = {tid: json.loads(g) for tid, g in t["goal_names"].items()}
        n_goals = max((len(v) for v in names.values()), default=0)
        probs = [json.loads(p) for p in s["probabilities"]]
        n_goals = max([n_goals, *(len(p) for p in probs)])
        prob_cols = [f"prob_{k}" for k in range(n_goals)]
        matrix = np.full((len(s), n_goals), np.nan)
        for i, p in enumerate(probs):
            matrix[i, : len(p)] = p
        out = s.copy()
        out["participant"] = out["trial_id"].map(t["participant"])
        out["predicted"] = [
            _goal_name(names.get(tid, []), k)
            for tid, k in zip(out["trial_id"], out["predicted"], strict=True)
        ]
        for k, col in enumerate(prob_cols):
            out[col] = matrix[:, k]
        columns = [c for s in SAMPLE_COLUMNS for c in (prob_cols if s == "probabilities" else [s])]
        out = out[[*SAMPLE_KEY, *columns]].reset_index(drop=True)
        return _typed(out, ints=("trial_id", "tick"), bools=())

    # -- sessions ----------------------------------------------------------------------------
    def sessions(self) -> pd.DataFrame:
        """One row per participant's session: status, times, and how they came (``source``:
        ``console`` or ``link``, with the recruitment IDs an open link carried). Like
        ``participants`` it lists every session, data retention aside: it holds no study data,
        and a panel's payment needs the recruitment ID of everyone who took part."""
        events = self.store.frame("events")
        rows = []
        rows_by = self.all_participants.set_index("participant")
        for s in self.store.sessions():
            mine = events[events["session_id"] == s.session_id]
            started = mine.loc[mine["kind"] == "start", "at"]
            enrol = mine.loc[mine["kind"] == "enrol", "detail"]
            detail = json.loads(enrol.iloc[0]) if len(enrol) else {}
            recruitment = detail.get("recruitment") or {}
            row = {
                "participant": s.participant,
                "session_id": s.session_id,
                "schedule_row": rows_by.loc[s.participant, "schedule_row"],
                "status": s.status,
                "enrolled_at": s.created_at,
                "started_at": started.iloc[0] if len(started) else None,
                "ended_at": s.ended_at,
                "source": "link" if recruitment else "console",
            }
            for param, column in RECRUITMENT_COLUMNS.items():
                row[column] = recruitment.get(param)
            rows.append(row)
        out = pd.DataFrame(rows, columns=list(SESSION_COLUMNS))
        return _typed(out, ints=("session_id", "schedule_row"), bools=())

    # -- ratings and events ------------------------------------------------------------------
    def ratings(self) -> pd.DataFrame:
        r = self.raw_ratings[list(RATING_COLUMNS)].reset_index(drop=True)
        return _typed(r, ints=("session_id", "value", "trial_id"), bools=())

    def answers(self) -> pd.DataFrame:
        """One row per answer to a non-Likert item; ``option`` is a choice's 1-based position
        among its options, ``correct`` whether an attention check was passed."""
        a = self.raw_answers.copy()
        items = self.protocol.questionnaire.items if self.protocol is not None else {}

        def option(item: str, value: Any) -> Any:
            spec = items.get(item)
            if isinstance(spec, ChoiceItem) and value in spec.options:
                return spec.code(value)
            return pd.NA

        def correct(item: str, value: Any) -> Any:
            spec = items.get(item)
            return spec.passed(value) if isinstance(spec, AttentionItem) else pd.NA

        a["option"] = [option(i, v) for i, v in zip(a["item"], a["value"], strict=True)]
        a["correct"] = [correct(i, v) for i, v in zip(a["item"], a["value"], strict=True)]
        out = a[list(ANSWER_COLUMNS)].reset_index(drop=True)
        return _typed(out, ints=("session_id", "option"), bools=("correct",), floats=("number",))

    def participant_table(self, answers: pd.DataFrame) -> pd.DataFrame:
        """One row per enrolled participant: session, whether their data are included and
        why not, the retention answer, attention checks, and each item asked once."""
        sessions = self.store.frame("sessions").set_index("participant")
        p = self.all_participants.sort_values("participant", kind="stable").copy()
        p["session_id"] = p["participant"].map(sessions["session_id"])
        p["status"] = p["participant"].map(sessions["status"])
        p["included"] = p["participant"].isin(self.retention.kept)
        p["excluded_because"] = p["participant"].map(self.retention.excluded).astype("string")
        p["retention"] = p["participant"].map(self.retention.answers).astype("string")
        checks = answers[answers["kind"] == "attention"]
        p["attention_checks"] = p["participant"].map(checks.groupby("participant").size())
        failed = checks[checks["correct"].eq(False).fillna(False)]
        p["attention_failures"] = p["participant"].map(failed.groupby("participant").size())
        for c in ("attention_checks", "attention_failures"):
            p[c] = p[c].where(~p["included"], p[c].fillna(0))
        between = list(self.protocol.between_factors) if self.protocol is not None else []
        for factor in between:  # the participant's level of each between-subjects factor
            levels = {
                row: self.protocol.group_for(int(row)).levels[factor]  # type: ignore[union-attr]
                for row in p["schedule_row"].dropna().unique()
            }
            p[factor] = p["schedule_row"].map(levels).astype("string")
        q = self.protocol.questionnaire if self.protocol is not None else None
        extra = []
        once = [i.id for i in q.once_items if i.kind not in ("attention", "retention")] if q else []
        for item in once:
            column = participant_item_column(item)
            rows = answers[answers["item"] == item]
            by = rows.set_index("participant")
            if (rows["kind"] == "number").any():
                p[column] = p["participant"].map(by["number"]).astype(float)
            else:
                p[column] = p["participant"].map(by["value"]).astype("string")
            extra.append(column)
        first, rest = PARTICIPANT_COLUMNS[:3], PARTICIPANT_COLUMNS[3:]  # ... schedule_row, then
        out = p[[*first, *between, *rest, *extra]].reset_index(drop=True)
        return _typed(
            out,
            ints=("session_id", "schedule_row", "attention_checks", "attention_failures"),
            bools=("included",),
        )

    def events(self) -> pd.DataFrame:
        e = self.store.frame("events").sort_values("event_id", kind="stable")
        e = e[e["participant"].isna() | e["participant"].isin(self.retention.kept)]
        return _typed(e[list(EVENT_COLUMNS)].reset_index(drop=True), ints=("session_id",), bools=())


_COUNTED = ("contact", "knocked_over", "pushed_off", "dropped", "lift_failed", "object_reset")
"""The event kinds whose totals are trial columns (a tick without one is not decoded)."""


def _with_event_totals(trials: pd.DataFrame, samples: pd.DataFrame) -> pd.DataFrame:
    """Per trial, from the samples' events: ``contacts`` (touch onsets of the arm on objects)
    and ``contact_impulse_ns`` (``app.trial.contacts``), and the accident counts
    (``app.trial.accidents.ACCIDENT_MEASURES``: knocks, pushes off the table, drops, resets).
    A trial without such events (or a store that predates them) has zeros."""
    text = samples["events"].astype(str)
    marked = samples[text.str.contains("|".join(_COUNTED), regex=True)]
    lists: dict[Any, list[TrialEvent]] = {}
    for tid, events in zip(marked["trial_id"], marked["events"], strict=True):
        lists.setdefault(tid, []).extend(decode_events(events))
    contacts = {tid: contact_totals(e) for tid, e in lists.items()}
    trials["contacts"] = trials["trial_id"].map(lambda k: contacts.get(k, (0, 0.0))[0])
    trials["contact_impulse_ns"] = trials["trial_id"].map(lambda k: contacts.get(k, (0, 0.0))[1])
    target = trials["target"] if "target" in trials else pd.Series("", index=trials.index)
    targets = dict(zip(trials["trial_id"], target, strict=True))
    for name in ACCIDENT_MEASURES:
        trials[name] = 0
    for tid, events in lists.items():
        rows = trials["trial_id"] == tid
        for name, value in accident_totals(events, target=str(targets.get(tid, ""))).items():
            trials.loc[rows, name] = value
    return trials


def _goal_name(names: list[str], index: Any) -> Any:
    if index is None or pd.isna(index):
        return pd.NA
    k = int(index)
    if not 0 <= k < len(names):
        raise ExportError(f"a sample predicts goal {k}, but its trial has goals {names}")
    return names[k]


def _typed(
    df: pd.DataFrame,
    *,
    ints: tuple[str, ...],
    bools: tuple[str, ...],
    floats: tuple[str, ...] = (),
) -> pd.DataFrame:
    """Nullable integer / boolean columns, text columns as pandas strings."""
    df = df.copy()
    for c in df.columns:
        if c in floats:
            df[c] = pd.to_numeric(df[c], errors="raise").astype(float)
        elif c in ints:
            df[c] = pd.array(pd.to_numeric(df[c], errors="raise"), dtype="Int64")
        elif c in bools:
            df[c] = df[c].astype("boolean")
        elif df[c].dtype == object:
            values = df[c]
            if values.map(lambda v: v is pd.NA or v is None or isinstance(v, str)).all():
                df[c] = values.astype("string")
            else:
                df[c] = pd.to_numeric(values, errors="raise")
    return df

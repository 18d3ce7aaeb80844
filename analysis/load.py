"""Tidy study tables from a SQLite store, an export directory, or DataFrames in memory.

The tables and their columns are the team contract's (``study.export.tidy_tables``): trials,
samples, ratings, answers, participants, events (answers and participants are optional: older
exports have none). Loading normalises types (participant ids as text, JSON columns as
Python lists, ``success`` as bool) and checks the columns the analyses need, so every later
step can trust them. ``task_cells`` then gives one row per participant, task and mode.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.design import require_columns
from analysis.errors import SchemaError, SourceError
from app.errors import AppError
from study.errors import StudyError
from study.store import Store

TABLES = ("trials", "samples", "ratings", "answers", "participants", "events")
TRIAL_COLUMNS = ("participant", "phase", "task", "mode", "status", "duration_s")
"""Columns every trials table has; the factors' columns are the protocol's (below)."""
PAPER_FACTORS = ("difficulty", "correctness", "mode")
"""The paper's factors: the columns of its protocol's trials table (and ``task_cells``' default)."""
COVARIATES = ("training_time_s", "baseline_rating", "tasks_completed")
RATING_ITEMS = ("helpful", "matched", "teammate")
SAMPLE_COLUMNS = ("trial_id", "t", "target_x", "target_y", "target_z")


@dataclass(frozen=True)
class StudyTables:
    """The tidy tables of one study and where they came from."""

    trials: pd.DataFrame
    samples: pd.DataFrame
    ratings: pd.DataFrame
    events: pd.DataFrame
    source: str
    protocol_hash: str | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    answers: pd.DataFrame = field(default_factory=pd.DataFrame)
    """Answers to the items other than ratings (demographics, attention checks, comments)."""
    participants: pd.DataFrame = field(default_factory=pd.DataFrame)
    """One row per enrolled participant: ``included``, ``excluded_because`` (data retention),
    attention checks (empty for data without the table)."""

    @property
    def excluded(self) -> dict[str, str]:
        """``{participant: why}`` for everyone whose data were left out (data retention)."""
        p = self.participants
        if p.empty or "included" not in p.columns:
            return {}
        out = p[~as_bool(p["included"])]
        return dict(
            zip(out["participant"].astype(str), out["excluded_because"].astype(str), strict=True)
        )


def _json_list(value: Any) -> Any:
    if isinstance(value, str):
        try:
            return json.loads(value)
        except json.JSONDecodeError as e:
            raise SchemaError(
                f"cannot parse JSON list {value[:60]!r}: {e}; the goal_names and "
                "goal_positions columns must hold JSON lists"
            ) from e
    if isinstance(value, np.ndarray):
        return [_json_list(v) for v in value.tolist()] if value.dtype == object else value.tolist()
    if isinstance(value, list | tuple):
        return [_json_list(v) if isinstance(v, np.ndarray) else v for v in value]
    return value


def as_bool(s: pd.Series) -> pd.Series:
    if pd.api.types.is_bool_dtype(s):
        return s
    mapping = {"true": True, "false": False, "1": True, "0": False, "1.0": True, "0.0": False}
    return s.map(lambda v: mapping.get(str(v).strip().lower(), bool(v) if v == v else False))


def normalise_trials(trials: pd.DataFrame) -> pd.DataFrame:
    """Check the trial columns the analysis needs and normalise their types."""
    require_columns(trials, TRIAL_COLUMNS, what="the trials table")
    t = trials.copy()
    t["participant"] = t["participant"].astype(str)
    for c in ("phase", "task", *PAPER_FACTORS, "status"):
        if c in t.columns:  # a protocol of other factors has no difficulty, correctness
            t[c] = t[c].astype("string").fillna("").astype(str)
    for c in ("goal_names", "goal_positions"):
        if c in t.columns:
            t[c] = t[c].map(_json_list)
    if "success" in t.columns:
        t["success"] = as_bool(t["success"])
    for c in (
        "duration_s",
        *COVARIATES,
        *RATING_ITEMS,
        "preference",
        "preference_aggressive",
        "position",
        "attempt",
    ):
        if c in t.columns:
            t[c] = pd.to_numeric(t[c], errors="coerce")
    return t


def normalise_samples(samples: pd.DataFrame) -> pd.DataFrame:
    if samples.empty and not len(samples.columns):
        return pd.DataFrame(columns=list(SAMPLE_COLUMNS))
    require_columns(samples, SAMPLE_COLUMNS, what="the samples table")
    return samples


def from_frames(
    trials: pd.DataFrame,
    samples: pd.DataFrame | None = None,
    ratings: pd.DataFrame | None = None,
    events: pd.DataFrame | None = None,
    *,
    answers: pd.DataFrame | None = None,
    participants: pd.DataFrame | None = None,
    source: str = "in-memory tables",
    protocol_hash: str | None = None,
) -> StudyTables:
    """Wrap tables already in memory (e.g. ``study.export.tidy_tables(...)``'s result)."""
    empty = pd.DataFrame()
    tables = StudyTables(
        trials=normalise_trials(trials),
        samples=normalise_samples(samples if samples is not None else empty),
        ratings=ratings if ratings is not None else empty,
        events=events if events is not None else empty,
        answers=answers if answers is not None else empty,
        participants=participants if participants is not None else empty,
        source=source,
        protocol_hash=protocol_hash,
    )
    excluded = tables.excluded
    if not excluded:
        return tables
    why = "; ".join(f"{p}: {w}" for p, w in excluded.items())
    note = f"{len(excluded)} participant(s) left out: their data may not be kept or used ({why})"
    return dataclasses.replace(tables, notes=(*tables.notes, note))


def from_store(path: str | Path) -> StudyTables:
    """Read a study's SQLite store through ``study.export.tidy_tables`` (read-only)."""
    p = Path(path)
    if not p.exists():
        raise SourceError(f"no study store at {p}; check the --db path")
    # study.export loads study.protocol, hence app.robot (pinocchio, scipy.linalg): +0.8-1.1 s
    # (-X importtime) that `python -m analysis anova` on exported files must not pay
    from study.export import tidy_tables

    try:
        tables = tidy_tables(p)
    except (StudyError, AppError) as e:  # the store's own typed errors say what is wrong
        raise SourceError(f"cannot read the study store {p}: {e}") from e
    missing = [t for t in ("trials",) if t not in tables]
    if missing:
        raise SourceError(f"tidy_tables({p}) returned no {missing} table")
    return from_frames(
        tables["trials"],
        tables.get("samples"),
        tables.get("ratings"),
        tables.get("events"),
        answers=tables.get("answers"),
        participants=tables.get("participants"),
        source=str(p),
        protocol_hash=_store_protocol_hash(p),
    )


def _store_protocol_hash(path: Path) -> str | None:
    try:
        with Store.open_readonly(path) as store:
            return str(store.meta.protocol_hash)
    except StudyError:  # the hash is informative; the data were already read
        return None


FORMATS = {"parquet": pd.read_parquet, "csv": pd.read_csv}
"""Table file formats of an export folder, in the order they are preferred."""


def _export_metadata(directory: Path) -> dict[str, Any]:
    """``metadata.json`` of an export folder (``{}`` without one, e.g. for hand-made folders)."""
    f = directory / "metadata.json"
    if not f.is_file():
        return {}
    try:
        meta = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise SourceError(
            f"cannot read {f}: {e}; export the store again (`python -m study "
            "export`) or remove the file"
        ) from e
    if not isinstance(meta, dict):
        raise SourceError(
            f"{f} is not an export's metadata (not a JSON object); export the "
            "store again (`python -m study export`) or remove the file"
        )
    return meta


def _export_formats(directory: Path, meta: dict[str, Any]) -> tuple[str, ...]:
    """The table formats to read: those ``metadata.json`` says were written, else all."""
    listed = meta.get("formats")
    if listed is None:
        return tuple(FORMATS)
    if not isinstance(listed, list) or not listed or any(f not in FORMATS for f in listed):
        raise SourceError(
            f"{directory / 'metadata.json'} lists table formats {listed!r}; "
            f"expected a list of {', '.join(FORMATS)}; export the store again"
        )
    return tuple(f for f in FORMATS if f in listed)


def _read_table(
    directory: Path, name: str, formats: tuple[str, ...] = tuple(FORMATS)
) -> tuple[pd.DataFrame, Path] | None:
    for suffix in formats:
        f = directory / f"{name}.{suffix}"
        if f.exists():
            try:
                return FORMATS[suffix](f), f
            except Exception as e:  # pandas and pyarrow raise many kinds for a damaged file
                raise SourceError(f"cannot read {f}: {e}") from e
    return None


def _check_rows(
    directory: Path, name: str, found: tuple[pd.DataFrame, Path] | None, meta: dict[str, Any]
) -> None:
    """The table has as many rows as ``metadata.json`` says the export wrote."""
    rows = meta.get("rows")
    expected = rows.get(name) if isinstance(rows, dict) else None
    if not isinstance(expected, int) or isinstance(expected, bool):
        return
    again = (
        "; the folder mixes files of different exports or a file was changed - export "
        "the store again (`python -m study export`) into this folder or a new one"
    )
    if found is None:
        if expected:
            raise SourceError(
                f"{directory} has no {name} table, but its metadata.json says "
                f"the export wrote {expected} rows{again}"
            )
        return
    df, f = found
    if len(df) != expected:
        raise SourceError(
            f"{f} has {len(df)} rows, but {directory / 'metadata.json'} says the "
            f"export wrote {expected}{again}"
        )


def from_export(directory: str | Path) -> StudyTables:
    """Read ``trials``/``samples``/``ratings``/``events`` as Parquet (preferred) or CSV files.

    With a ``metadata.json`` (``python -m study export`` writes one) only the formats it lists
    are read, and each table must have the number of rows it records (``SourceError`` if not,
    e.g. when the folder holds files of an earlier export)."""
    d = Path(directory)
    if not d.is_dir():
        raise SourceError(f"{d} is not a directory; pass the folder `python -m study export` wrote")
    meta = _export_metadata(d)
    formats = _export_formats(d, meta)
    found = {name: _read_table(d, name, formats) for name in TABLES}
    if found["trials"] is None:
        wanted = " or ".join(f"trials.{f}" for f in formats)
        raise SourceError(f"{d} holds no {wanted}; pass the folder `python -m study export` wrote")
    for name in TABLES:
        _check_rows(d, name, found[name], meta)
    tables = {name: (v[0] if v is not None else None) for name, v in found.items()}
    return from_frames(
        tables["trials"],
        tables["samples"],
        tables["ratings"],
        tables["events"],
        answers=tables["answers"],
        participants=tables["participants"],
        source=str(d),
        protocol_hash=_export_protocol_hash(d),
    )


def _export_protocol_hash(directory: Path) -> str | None:
    for f in sorted(directory.glob("*.json")):
        try:
            meta = json.loads(f.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):  # not an export's metadata
            continue
        if isinstance(meta, dict):
            for key in ("protocol_hash", "content_hash"):
                if isinstance(meta.get(key), str):
                    return meta[key]
            inner = meta.get("protocol")
            if isinstance(inner, dict) and isinstance(inner.get("hash"), str):
                return inner["hash"]
    return None


def load_tables(
    *, db: str | Path | None = None, export_dir: str | Path | None = None
) -> StudyTables:
    """Tidy tables from exactly one of a store (``db``) or an export directory."""
    if (db is None) == (export_dir is None):
        raise SourceError(
            "give exactly one source: a study store (--db) or an export directory (--export-dir)"
        )
    return from_store(db) if db is not None else from_export(export_dir)  # type: ignore[arg-type]


def task_cells(
    trials: pd.DataFrame,
    *,
    successful_only: bool = False,
    factors: tuple[str, ...] = PAPER_FACTORS,
) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """One row per participant, task and condition (the levels of ``factors``, default the
    paper's: one row per task and mode): the completed task trial of each cell.

    Training runs, redone, skipped and interrupted attempts are left out. Completed trials
    that ended without success (dropped, wrong object, timeout) are kept with a note - their
    duration is the time until the trial ended - or left out with ``successful_only=True``
    (their cells then count as missing). A cell completed more than once is averaged
    (numeric columns) with a note.
    """
    t = trials
    notes: list[str] = []
    done = t[(t["phase"] == "task") & (t["status"] == "completed")]
    other = t[(t["phase"] == "task") & (t["status"] != "completed")]
    if len(other):
        counts = other["status"].value_counts().to_dict()
        notes.append("task attempts left out: " + ", ".join(f"{v} {k}" for k, v in counts.items()))
    if "success" in done.columns and (~done["success"].astype(bool)).any():
        failed = done[~done["success"].astype(bool)]
        outcomes = failed["outcome"].value_counts().to_dict() if "outcome" in failed else {}
        what = ", ".join(f"{v} {k}" for k, v in outcomes.items())
        if successful_only:
            done = done[done["success"].astype(bool)]
            notes.append(
                f"{len(failed)} completed task trial(s) ended without success "
                f"({what}) and were left out (successful trials only)"
            )
        else:
            notes.append(
                f"{len(failed)} completed task trial(s) ended without success "
                f"({what}); their duration (until the trial ended, e.g. the time "
                "limit) is analysed as is (--successful-only leaves them out)"
            )
    keys = list(dict.fromkeys(["participant", "task", *factors]))
    require_columns(t, keys, what="the trials table")
    dup = done.duplicated(keys, keep=False)
    if dup.any():
        notes.append(
            f"{int(dup.sum())} completed trials share a participant/task/mode cell; "
            "their values were averaged"
        )
        numeric = [
            c for c in done.columns if c not in keys and pd.api.types.is_numeric_dtype(done[c])
        ]
        first = done.groupby(keys, as_index=False, sort=False).first()
        means = done.groupby(keys, as_index=False, sort=False)[numeric].mean()
        done = first.drop(columns=numeric).merge(means, on=keys)
    return done.reset_index(drop=True), tuple(notes)

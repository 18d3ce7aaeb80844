"""A trial's records in one ``.npz`` file: ``save_records`` and ``load_records``.

One array per stored field of ``app.trial.samples.SAMPLE_FIELDS``, named by its ``TickRecord``
attribute (a row per tick; a vector or a probability list as a row of floats), plus ``tick``;
and ``meta``, JSON text with the trial's summary, its goal names, its events as ``[t, text]``
pairs and each tick's events (``tick_events``, as text: ``app.trial.events``). A field a file
predates loads as the ``TickRecord`` default.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from app.trial.events import decode, encode
from app.trial.records import TickRecord, TrialResult
from app.trial.samples import SAMPLE_FIELDS, ColumnKind

_DTYPES = {ColumnKind.REAL: float, ColumnKind.INDEX: np.int64, ColumnKind.FLOATS: float}


def save_records(result: TrialResult, path: str | Path) -> Path:
    """Write a trial's records to ``path`` (``.npz``); returns the file written."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    recs = result.records
    arrays: dict[str, np.ndarray] = {"tick": np.array([r.tick for r in recs], dtype=np.int64)}
    meta: dict[str, Any] = {
        **result.summary(),
        "goal_names": list(result.goal_names),
        "events": [[t, encode(e)] for t, e in result.events],
    }
    for f in SAMPLE_FIELDS:
        values = [getattr(r, f.attr) for r in recs]
        if f.kind is ColumnKind.EVENTS:
            meta[f"tick_{f.attr}"] = [[encode(e) for e in events] for events in values]
        elif f.axes or f.kind is ColumnKind.FLOATS:
            arrays[f.attr] = np.array(values, dtype=float).reshape(len(recs), -1)
        else:
            arrays[f.attr] = np.array(values, dtype=_DTYPES[f.kind])
    np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
    return path if path.suffix == ".npz" else path.with_name(path.name + ".npz")


def load_records(path: str | Path) -> tuple[dict[str, Any], tuple[TickRecord, ...]]:
    """Read what ``save_records`` wrote: ``(meta, records)`` (``meta["events"]`` stays
    ``[t, text]`` pairs; ``app.trial.events.decode`` reads a text)."""
    with np.load(Path(path), allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        cols = {k: z[k] for k in z.files if k != "meta"}
    fields: dict[str, list[Any]] = {}
    for f in SAMPLE_FIELDS:
        if f.kind is ColumnKind.EVENTS:
            if f"tick_{f.attr}" in meta:
                stored = meta[f"tick_{f.attr}"]
                fields[f.attr] = [tuple(decode(e) for e in events) for events in stored]
        elif f.attr in cols:
            column = cols[f.attr]
            if column.ndim == 2:
                fields[f.attr] = list(column)
            else:
                fields[f.attr] = [
                    int(v) if f.kind is ColumnKind.INDEX else float(v) for v in column
                ]
    records = tuple(
        TickRecord(tick=int(tick), **{attr: values[i] for attr, values in fields.items()})
        for i, tick in enumerate(cols["tick"])
    )
    return meta, records

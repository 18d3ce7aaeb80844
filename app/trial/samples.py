"""The samples layout: which ``TickRecord`` fields a study keeps per control tick, in which
columns, of which type and unit -- declared once, in ``SAMPLE_FIELDS``.

Everything else derives from it: the store's ``samples`` table and its insert
(``study.store.schema``), the sample writer's rows (``sample_row``), the export's
``samples`` columns and their codebook entries (``study.export``, ``study.codebook``), and
``records_from_samples``, which rebuilds tick records from stored rows. A row is the key
(``trial_id``, ``tick``: the store's, not a record field) followed by ``SAMPLE_COLUMNS``.

Adding a column is one line here, e.g.::

    SampleField.scalar("rationality", "the user's rationality estimated online", "1/m"),

(plus the ``TickRecord`` attribute it reads). A store file opened read-write gets the new
column (``NULL`` for the ticks written before); a read-only one reads it as ``NULL``.

Kinds (``ColumnKind``): ``real`` -- one float per column, a vector spread over several
(``q1..q7``, ``target_x..z``); ``index`` -- an integer or empty; ``floats`` -- a list of floats
as JSON text (``probabilities``, one per goal); ``events`` -- the tick's events as a JSON list
of their text (``app.trial.events``).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from app.robot.scene_spec import ARM_DOF
from app.trial.errors import TrialError
from app.trial.events import decode_events, encode_events
from app.trial.records import TickRecord

_COLUMN = re.compile(r"[a-z_][a-z0-9_]*")


class SampleLayoutError(TrialError, ValueError):
    """A tick record or a samples table does not fit the layout; the message names the field."""


class ColumnKind(StrEnum):
    """How a field's value is stored (see the module docstring)."""

    REAL = "real"
    INDEX = "index"
    FLOATS = "floats"
    EVENTS = "events"


SQL_TYPES = {
    ColumnKind.REAL: "REAL",
    ColumnKind.INDEX: "INTEGER",
    ColumnKind.FLOATS: "TEXT NOT NULL",
    ColumnKind.EVENTS: "TEXT NOT NULL DEFAULT '[]'",
}
"""SQLite column type of each kind in a new store."""

ADDED_SQL_TYPES = {**SQL_TYPES, ColumnKind.FLOATS: "TEXT"}
"""The type of a column added to an existing store (it cannot be ``NOT NULL`` without a
default: the ticks written before have no value)."""


@dataclass(frozen=True)
class SampleField:
    """One ``TickRecord`` attribute ``attr`` stored in ``columns`` (several for a vector).

    ``description`` and ``unit`` are the codebook's; a vector's description holds ``{axis}``,
    replaced by each column's axis (``1``..``7`` or ``x``, ``y``, ``z``).
    """

    attr: str
    kind: ColumnKind
    description: str
    unit: str
    columns: tuple[str, ...]
    axes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # both are written into source: the row function (attr) and SQL (columns)
        bad = [c for c in self.columns if not _COLUMN.fullmatch(c)]
        if not self.attr.isidentifier() or bad or not self.columns:
            raise SampleLayoutError(
                f"sample field {self.attr!r}: the attribute must be a Python name and the"
                f" columns {list(self.columns)} lower-case SQL names ([a-z_][a-z0-9_]*)"
            )

    @classmethod
    def scalar(
        cls,
        attr: str,
        description: str,
        unit: str,
        *,
        kind: ColumnKind = ColumnKind.REAL,
        column: str | None = None,
    ) -> SampleField:
        """A field stored in one column (named ``attr`` unless ``column`` says otherwise)."""
        return cls(attr, kind, description, unit, (column or attr,))

    @classmethod
    def vector(
        cls, attr: str, prefix: str, axes: Sequence[str], description: str, unit: str
    ) -> SampleField:
        """A real vector: one column per axis, ``<prefix><axis>``."""
        return cls(
            attr,
            ColumnKind.REAL,
            description,
            unit,
            tuple(f"{prefix}{a}" for a in axes),
            tuple(axes),
        )

    def docs(self) -> dict[str, tuple[str, str]]:
        """``{column: (description, unit)}`` for the codebook."""
        if not self.axes:
            return {self.columns[0]: (self.description, self.unit)}
        return {
            c: (self.description.format(axis=a), self.unit)
            for c, a in zip(self.columns, self.axes, strict=True)
        }


JOINTS = tuple(str(i) for i in range(1, ARM_DOF + 1))
XYZ = ("_x", "_y", "_z")

SAMPLE_FIELDS: tuple[SampleField, ...] = (
    SampleField.scalar("t", "trial time at this tick, seconds, pauses excluded", "s"),
    SampleField.vector("q", "q", JOINTS, "robot configuration Q, joint {axis}", "rad"),
    SampleField.vector("u", "u", JOINTS, "user's next configuration U, joint {axis}", "rad"),
    SampleField.vector(
        "p", "p", JOINTS, "robot's predicted next configuration P, joint {axis}", "rad"
    ),
    SampleField.vector(
        "command", "cmd", JOINTS, "blended command (1 - alpha) U + alpha P, joint {axis}", "rad"
    ),
    SampleField.scalar(
        "alpha", "arbitration alpha in [0, 1]: weight of the robot's prediction", "0..1"
    ),
    SampleField.scalar("confidence", "the robot's confidence in its predicted goal", "0..1"),
    SampleField.scalar(
        "predicted", "index of the goal the robot predicts", "", kind=ColumnKind.INDEX
    ),
    SampleField.scalar(
        "probabilities", "P(goal | trajectory so far), one per goal", "0..1", kind=ColumnKind.FLOATS
    ),
    SampleField.vector(
        "user_target",
        "target",
        XYZ,
        "user target (the interface's absolute end-effector input, clamped to the reach; under"
        " a relative mapping the path the user's own input traced), {axis}",
        "m",
    ),
    SampleField.vector("ee", "ee", XYZ, "end-effector position, {axis}", "m"),
    SampleField.scalar("gripper", "gripper opening", "m"),
    SampleField.scalar(
        "events",
        "JSON list of events at this tick (grasp_requested, grasped:<object>, "
        "lifted:<object>, goal_moved:<object>@x,y,z when the robot re-aims at a moved "
        "object, contact:<part>:<object> when an arm part starts touching an object, "
        "contact_end:<part>:<object>:<impulse N s> when it stops, "
        "pushed_off:<object>, outcome:<outcome> ...; app.trial.events)",
        "",
        kind=ColumnKind.EVENTS,
    ),
    SampleField.scalar(
        "motion_agreement",
        "cosine of the user's actual motion (their input's latest cm) and the robot's heading "
        "to its predicted goal (Fig. 15; 0 before the user moves; empty in older stores)",
        "-1..1",
    ),
    SampleField.scalar(
        "rationality",
        "the user's rationality toward the predicted goal, estimated online from their recent "
        "motion (eq. 9's b for the path-length cost; 11.3 = no evidence yet)",
        "1/m",
    ),
)
"""The per-tick sample layout, in column order."""

SAMPLE_COLUMNS: tuple[str, ...] = tuple(c for f in SAMPLE_FIELDS for c in f.columns)
"""The data columns of a sample row, in order (after the key ``trial_id``, ``tick``)."""

SAMPLE_DOCS: dict[str, tuple[str, str]] = {
    c: doc for f in SAMPLE_FIELDS for c, doc in f.docs().items()
}
"""``{column: (description, unit)}`` of every data column."""


# -- writing: record -> row -----------------------------------------------------------------
def _vector(value: Any, n: int, attr: str) -> list[Any]:
    values = value.tolist() if hasattr(value, "tolist") else list(value)
    if len(values) != n:
        raise SampleLayoutError(
            f"tick record field {attr!r} has {len(values)} values, expected {n}"
        )
    return values


def _floats(value: Any) -> str:
    values = value.tolist() if hasattr(value, "tolist") else list(value)
    text = str([float(x) for x in values])  # JSON for finite floats, 3x faster than json.dumps
    return json.dumps(values) if "n" in text else text  # nan or inf: let json spell them


def _expression(f: SampleField) -> str:
    """Python source of field ``f``'s column value(s) in a row, read from ``record``."""
    value = f"record.{f.attr}"
    if f.axes:
        return f"*_vector({value}, {len(f.axes)}, {f.attr!r})"
    return {
        ColumnKind.REAL: f"float({value})",
        ColumnKind.INDEX: f"None if {value} is None else int({value})",
        ColumnKind.FLOATS: f"_floats({value})",
        ColumnKind.EVENTS: f"encode_events({value})",
    }[f.kind]


ROW_SOURCE = (
    "def sample_row(trial_id, tick, record):\n"
    f"    return (trial_id, tick, {', '.join(_expression(f) for f in SAMPLE_FIELDS)})\n"
)
"""The source of ``sample_row``, written out from ``SAMPLE_FIELDS``: one tuple expression, e.g.
``(trial_id, tick, float(record.t), *_vector(record.q, 7, 'q'), ...)``. The control loop pays
for a row every tick, mostly with cold caches; measured (``benchmarks/store.py`` ``add_us``
conditions, median): 41 us for this or the hand-written row it replaces, 55 us for a loop over
the fields, so the row is written out once, as ``dataclasses`` writes ``__init__``."""

_namespace: dict[str, Any] = {
    "_vector": _vector,
    "_floats": _floats,
    "encode_events": encode_events,
}
exec(ROW_SOURCE, _namespace)  # our own source, built from SAMPLE_FIELDS above
sample_row: Callable[[int, int, TickRecord], tuple[Any, ...]] = _namespace["sample_row"]
"""``sample_row(trial_id, tick, record)``: the store's ``samples`` row of one tick record (the
key, then ``SAMPLE_COLUMNS``: vectors spread, lists as JSON text)."""


# -- reading: a samples table -> tick records ----------------------------------------------
def _column_values(f: SampleField, samples: Any) -> Sequence[Any]:
    """Per-row values of field ``f`` from a samples DataFrame."""
    if f.axes:
        return samples[list(f.columns)].to_numpy(dtype=float)
    values = samples[f.columns[0]].tolist()
    if f.kind is ColumnKind.REAL:  # empty (a column the store predates): nan
        return [np.nan if v is None else float(v) for v in values]
    if f.kind is ColumnKind.INDEX:
        return [int(v) for v in values]
    if f.kind is ColumnKind.FLOATS:
        return [np.array(json.loads(v) if isinstance(v, str) else v, dtype=float) for v in values]
    return [decode_events(v) for v in values]


def records_from_samples(samples: Any) -> tuple[TickRecord, ...]:
    """Tick records from a study store's ``samples`` rows of one trial (a pandas DataFrame with
    ``tick`` and ``SAMPLE_COLUMNS``, lists as JSON text or lists; ``tick`` is the stored one)."""
    missing = [c for c in ("tick", *SAMPLE_COLUMNS) if c not in samples.columns]
    if missing:
        raise SampleLayoutError(f"samples: missing column(s) {missing}")
    ticks = [int(v) for v in samples["tick"].tolist()]
    fields = {f.attr: _column_values(f, samples) for f in SAMPLE_FIELDS}
    return tuple(
        TickRecord(tick=tick, **{attr: values[i] for attr, values in fields.items()})
        for i, tick in enumerate(ticks)
    )

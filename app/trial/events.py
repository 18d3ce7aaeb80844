"""Trial events: what happened at a control tick, as typed values with one text codec.

A trial logs ``TrialEvent`` values on its tick records; the store, ``save_records`` files and
exports keep them as text, one string per event, in a JSON list per tick. ``encode`` and
``decode`` are the only place that text is written or read:

===================================  ==========================================================
text                                 meaning
===================================  ==========================================================
``<kind>``                           a mark: ``paused``, ``resumed``, ``grasp_requested``,
                                     ``grasp_missed``, ``objects_disturbed``, ``invalid_target``,
                                     ``target_clamped``, ``target_far_outside``, ``timeout``,
                                     ``aborted``, ``interrupted``
``<kind>:<object>``                  ``grasped``, ``lifted``, ``dropped``, ``lift_failed``,
                                     ``pushed_off``, ``knocked_over``, ``object_reset`` (put
                                     back at its start pose; ``obj``: the object)
``<kind>:<text>``                    ``outcome`` (the trial's outcome), ``input_error`` (the
                                     input source's exception type), ``physics_error`` (message)
``goal_moved:<goal>@<x>,<y>,<z>``    the robot re-aims at a moved object: goal ``obj`` is now at
                                     ``position`` (metres, world frame, 6 decimals)
``contact:<part>:<object>``          arm ``part`` starts touching ``obj``
``contact_end:<part>:<object>:<J>``  that touch ends; ``impulse_ns`` its normal impulse
                                     ``J`` (N s, 4 decimals)
===================================  ==========================================================

An event holds its numbers at the stored resolution (a position to the micrometre, an impulse
to 1e-4 N s), so ``decode(encode(e)) == e`` for every event, and ``encode(decode(s)) == s`` for
every string the trial writes: stores and exports written before events were typed read
unchanged.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from app.trial.errors import TrialError


class TrialEventError(TrialError, ValueError):
    """A trial event cannot be built or read; the message quotes the text or the values."""


class EventKind(StrEnum):
    """Every kind of trial event (the text before the first ``:``)."""

    PAUSED = "paused"
    RESUMED = "resumed"
    GRASP_REQUESTED = "grasp_requested"
    GRASP_MISSED = "grasp_missed"
    OBJECTS_DISTURBED = "objects_disturbed"
    INVALID_TARGET = "invalid_target"
    TARGET_CLAMPED = "target_clamped"
    TARGET_FAR_OUTSIDE = "target_far_outside"
    TIMEOUT = "timeout"
    ABORTED = "aborted"
    INTERRUPTED = "interrupted"
    GRASPED = "grasped"
    LIFTED = "lifted"
    DROPPED = "dropped"
    LIFT_FAILED = "lift_failed"
    PUSHED_OFF = "pushed_off"
    KNOCKED_OVER = "knocked_over"
    OBJECT_RESET = "object_reset"
    OUTCOME = "outcome"
    INPUT_ERROR = "input_error"
    PHYSICS_ERROR = "physics_error"
    GOAL_MOVED = "goal_moved"
    CONTACT = "contact"
    CONTACT_END = "contact_end"


OBJECT_KINDS = frozenset(
    {
        EventKind.GRASPED,
        EventKind.LIFTED,
        EventKind.DROPPED,
        EventKind.LIFT_FAILED,
        EventKind.PUSHED_OFF,
        EventKind.KNOCKED_OVER,
        EventKind.OBJECT_RESET,
    }
)
"""Kinds whose payload is one object name (``obj``)."""

TEXT_KINDS = frozenset({EventKind.OUTCOME, EventKind.INPUT_ERROR, EventKind.PHYSICS_ERROR})
"""Kinds whose payload is free text (``text``)."""

_FIELDS = ("obj", "part", "position", "impulse_ns", "text")


def _payload(kind: EventKind) -> frozenset[str]:
    """The fields an event of ``kind`` carries (the others are ``None``)."""
    if kind in OBJECT_KINDS:
        return frozenset({"obj"})
    if kind in TEXT_KINDS:
        return frozenset({"text"})
    if kind is EventKind.GOAL_MOVED:
        return frozenset({"obj", "position"})
    if kind is EventKind.CONTACT:
        return frozenset({"part", "obj"})
    if kind is EventKind.CONTACT_END:
        return frozenset({"part", "obj", "impulse_ns"})
    return frozenset()


@dataclass(frozen=True, slots=True)
class TrialEvent:
    """One event: its ``kind`` and the payload that kind carries (see the module table).

    ``obj``: an object or goal name; ``part``: an arm part (``app.robot.simulation.ARM_PARTS``);
    ``position``: (x, y, z) metres, rounded to 6 decimals; ``impulse_ns``: N s, rounded to 4;
    ``text``: outcome, error type or message. Build with the keywords a kind needs, e.g.
    ``TrialEvent(EventKind.GRASPED, obj="bottle")``; a missing or extra payload raises
    ``TrialEventError``.
    """

    kind: EventKind
    obj: str | None = None
    part: str | None = None
    position: tuple[float, float, float] | None = None
    impulse_ns: float | None = None
    text: str | None = None

    def __post_init__(self) -> None:
        kind = EventKind(self.kind)
        object.__setattr__(self, "kind", kind)
        needed = _payload(kind)
        for name in _FIELDS:
            if (getattr(self, name) is None) == (name in needed):
                what = "needs" if name in needed else "takes no"
                raise TrialEventError(f"a {kind.value!r} event {what} {name!r}: {self!r}")
        for name in ("obj", "part"):
            value = getattr(self, name)
            if value is not None and (not value or (name == "part" and ":" in value)):
                raise TrialEventError(f"a {kind.value!r} event's {name} {value!r} is not a name")
        if self.position is not None:
            position = tuple(float(v) for v in self.position)
            if len(position) != 3 or not all(math.isfinite(v) for v in position):
                raise TrialEventError(
                    f"goal {self.obj!r} moved to {self.position!r}: not (x, y, z)"
                )
            object.__setattr__(self, "position", tuple(float(f"{v:.6f}") for v in position))
        if self.impulse_ns is not None:
            object.__setattr__(self, "impulse_ns", float(f"{float(self.impulse_ns):.4f}"))


_MARKS = {kind: TrialEvent(kind) for kind in EventKind if not _payload(kind)}


def mark(kind: EventKind) -> TrialEvent:
    """The event of a kind that carries no payload (``TrialEvent(kind)``), built once: a tick
    that logs one (a hard task's user pushes past the reach on most ticks: ``target_clamped``)
    shares it rather than building and checking a new one."""
    try:
        return _MARKS[kind]
    except KeyError:
        raise TrialEventError(f"a {kind!r} event carries a payload: build it") from None


def encode(event: TrialEvent) -> str:
    """The stored text of ``event`` (the module table)."""
    kind = event.kind
    if kind is EventKind.GOAL_MOVED:
        x, y, z = event.position  # type: ignore[misc]
        return f"{kind}:{event.obj}@{x:.6f},{y:.6f},{z:.6f}"
    if kind is EventKind.CONTACT:
        return f"{kind}:{event.part}:{event.obj}"
    if kind is EventKind.CONTACT_END:
        return f"{kind}:{event.part}:{event.obj}:{event.impulse_ns:.4f}"
    if kind in OBJECT_KINDS:
        return f"{kind}:{event.obj}"
    if kind in TEXT_KINDS:
        return f"{kind}:{event.text}"
    return kind.value


def decode(text: str) -> TrialEvent:
    """The event stored as ``text``; ``TrialEventError`` (quoting it) if it is not one."""
    head, sep, rest = str(text).partition(":")
    try:
        kind = EventKind(head)
    except ValueError:
        known = ", ".join(k.value for k in EventKind)
        raise TrialEventError(
            f"trial event {text!r}: unknown kind {head!r} (known: {known})"
        ) from None
    needed = _payload(kind)
    if bool(sep) != bool(needed):
        form = "a bare kind" if not needed else f"'{kind}:...'"
        raise TrialEventError(f"trial event {text!r}: a {kind.value!r} event is written {form}")
    try:
        if kind is EventKind.GOAL_MOVED:
            name, at, coords = rest.rpartition("@")
            values = coords.split(",")
            if not at or len(values) != 3:
                raise TrialEventError("expected 'goal_moved:<name>@x,y,z'")
            x, y, z = (float(v) for v in values)
            return TrialEvent(kind, obj=name, position=(x, y, z))
        if kind is EventKind.CONTACT:
            part, _, obj = rest.partition(":")
            return TrialEvent(kind, part=part, obj=obj)
        if kind is EventKind.CONTACT_END:
            touch, _, impulse = rest.rpartition(":")
            part, _, obj = touch.partition(":")
            return TrialEvent(kind, part=part, obj=obj, impulse_ns=float(impulse))
        if kind in OBJECT_KINDS:
            return TrialEvent(kind, obj=rest)
        if kind in TEXT_KINDS:
            return TrialEvent(kind, text=rest)
        return TrialEvent(kind)
    except (TrialEventError, ValueError) as exc:
        raise TrialEventError(f"trial event {text!r} cannot be read: {exc}") from None


def encode_events(events: Sequence[TrialEvent]) -> str:
    """One tick's events as the JSON list text the store and exports keep (``"[]"`` if none)."""
    return json.dumps([encode(e) for e in events]) if events else "[]"


def decode_events(value: Any) -> tuple[TrialEvent, ...]:
    """One tick's events from what a table holds: JSON list text (store, CSV), a list or array
    of strings (Parquet), or an empty value (``None``, ``""``, NaN)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ()
    if isinstance(value, str):
        if not value.strip():
            return ()
        try:
            value = json.loads(value)
        except json.JSONDecodeError as exc:
            raise TrialEventError(f"tick events {value!r}: not a JSON list ({exc})") from None
        if not isinstance(value, list):
            raise TrialEventError(f"tick events {value!r}: not a JSON list")
    return tuple(decode(str(text)) for text in value)

"""One session's timeline for the console, from the store: its runs (condition, outcome, time)
and what happened around them (start, consent, pauses and their cause, reloads, redos, skips,
faults, the end), each with its clock time and the time since the session started.

Read from the store, so a session reopened after a restart shows its earlier runs and events
too. Experimenter side only: the rows name conditions.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime
from typing import Any, Protocol

from study.store import EventRecord, TrialRecord


class TaskLabelled(Protocol):
    """A row naming a task and the paper's task levels (a trial record, a session overview)."""

    @property
    def task(self) -> str | None: ...

    @property
    def difficulty(self) -> str | None: ...

    @property
    def correctness(self) -> str | None: ...


Row = tuple[str, str, str]
"""(clock time, time since the session started, what)."""


def started_at(events: Sequence[EventRecord]) -> datetime | None:
    """When the session was first started (its first ``start`` event), else ``None``."""
    for e in events:
        if e.kind == "start":
            return _when(e.at)
    return None


def timeline(
    events: Sequence[EventRecord], trials: Sequence[TrialRecord]
) -> tuple[tuple[Row, ...], str]:
    """The rows, oldest first, and a one-line tally of runs by outcome, pauses, reloads, redos
    and faults."""
    start = started_at(events)
    entries: list[tuple[str, str]] = [(t.started_at, run_text(t)) for t in trials]
    connected_before = False
    tally: Counter[str] = Counter()
    for e in events:
        text = _event_text(e, connected_before=connected_before)
        if e.kind == "participant_connected":
            if connected_before:
                tally["reloads"] += 1
            connected_before = True
        elif e.kind == "pause":
            tally["pauses"] += 1
        elif e.kind in ("redo", "control_fault", "skip"):
            tally[{"redo": "redos", "control_fault": "faults", "skip": "skips"}[e.kind]] += 1
        if text:
            entries.append((e.at, text))
    entries.sort(key=lambda item: item[0])
    rows = tuple((_clock(at), _since(at, start), text) for at, text in entries)
    outcomes = Counter(
        (t.outcome or t.status) for t in trials if t.status in ("completed", "running")
    )
    parts = [f"{what} {n}" for what, n in sorted(outcomes.items())]
    redone = sum(t.status in ("redone", "interrupted") for t in trials)
    if redone:
        parts.append(f"{redone} redone or interrupted")
    parts += [f"{k} {tally[k]}" for k in ("pauses", "reloads", "redos", "skips", "faults")]
    return rows, "runs: " + ", ".join(parts)


def task_text(t: TaskLabelled) -> str:
    """``easy-right (easy, right)``: the task and the paper's task levels where it has them
    (a protocol of other factors names them in its task names)."""
    levels = ", ".join(v for v in (t.difficulty, t.correctness) if v)
    return f"{t.task} ({levels})" if levels else str(t.task)


def run_text(t: TrialRecord) -> str:
    """A run as one line: number, phase, condition, attempt, and how it ended."""
    if t.task:
        cond = f"{task_text(t)}, mode **{t.mode}**, {t.run} run"
    else:
        cond = "practice, unassisted"
    attempt = f", attempt {t.attempt}" if t.attempt > 1 else ""
    if t.status == "running":
        end = "running"
    else:
        done = t.outcome not in (None, "aborted")
        end = f"**{t.outcome}**" if done else ""
        if t.status != "completed":
            note = t.note or ""
            why = note if note.startswith(t.status) else t.status + (f" ({note})" if note else "")
            end += (", then " if done else "") + why
    took = "" if t.duration_s is None else f" in {t.duration_s:.1f} s"
    return f"run {t.trial_number}: {cond}{attempt} -> {end}{took}"


_FIXED_TEXTS: dict[str, str] = {
    "start": "session started",
    "consent": "consent given",
    "resume": "resumed",
    "finish": "**completed**",
    "close": "server let the session go",
    "participant_disconnected": "tab lost",
    "second_tab_refused": "a second tab was refused",
    "link_place_released": "left before consent: its open-link place given back",
    "link_place_retaken": "back by the open link: holds a place again",
}
"""Events told the same way every time."""

_REASONED_TEXTS: dict[str, str] = {
    "redo": "redo",
    "skip": "skipped",
    "withdraw": "**withdrawn**",
    "end": "**ended**",
}
"""Experimenter actions, told with the reason given (``": <reason>"``)."""


def _pause_text(d: Mapping[str, Any]) -> str:
    return "paused: participant's tab lost" if d.get("cause") == "tab_lost" else "paused"


def _reopen_text(d: Mapping[str, Any]) -> str:
    n = len(d.get("interrupted") or ())
    return "session reopened" + (f" ({n} run interrupted)" if n else "")


_DETAILED_TEXTS: dict[str, Callable[[Mapping[str, Any]], str]] = {
    "enrol": lambda d: f"enrolled (schedule row {d.get('schedule_row')})",
    "pause": _pause_text,
    "reopen": _reopen_text,
    "control_fault": lambda d: f"**control fault**: `{str(d.get('error', ''))[:120]}`",
    "input_rejected": lambda d: f"input rejected: {str(d.get('problem', ''))[:80]}",
    "answer": lambda d: f"answered {len(d.get('items') or ())} item(s)",
}
"""Events told with what their detail holds."""


def _event_text(e: EventRecord, *, connected_before: bool) -> str:
    """One event as the timeline tells it ("" for an event it does not show)."""
    d = e.detail
    if e.kind in _FIXED_TEXTS:
        return _FIXED_TEXTS[e.kind]
    if e.kind in _REASONED_TEXTS:
        return _REASONED_TEXTS[e.kind] + (f": {d['reason']}" if d.get("reason") else "")
    if e.kind == "participant_connected":
        where = f" from {d['address']}" if d.get("address") else ""
        return ("tab reconnected (reload)" if connected_before else "tab connected") + where
    told = _DETAILED_TEXTS.get(e.kind)
    return "" if told is None else told(d)


def _when(iso: str) -> datetime | None:
    try:
        return datetime.fromisoformat(iso)
    except (TypeError, ValueError):
        return None


def _clock(iso: str) -> str:
    when = _when(iso)
    return when.astimezone().strftime("%H:%M:%S") if when is not None else "?"


def _since(iso: str, start: datetime | None) -> str:
    when = _when(iso)
    if when is None or start is None or when < start:
        return ""
    m, s = divmod(int((when - start).total_seconds()), 60)
    h, m = divmod(m, 60)
    return f"+{h}:{m:02d}:{s:02d}" if h else f"+{m:02d}:{s:02d}"


__all__ = ["run_text", "started_at", "timeline"]

"""The study's progress for the top of the console, read from the store.

Participants completed against the protocol's planned number (``[study] participants``), those
in progress and those who stopped early; success per condition over the task runs that ended
by themselves (the last completed attempt of each step, as the analysis counts them); and the
next participant's schedule row (``study.schedule.next_row``, the row the next enrolment gets)
with its order of conditions.
"""

from __future__ import annotations

from study.protocol import Protocol
from study.schedule import Design, Enrollment, next_row
from study.server.console_model import StudyProgress
from study.store import Store

STOPPED = ("withdrawn", "ended")


def study_progress(store: Store, protocol: Protocol) -> StudyProgress:
    """See module docstring."""
    sessions = store.sessions()
    statuses = [s.status for s in sessions]
    last: dict[tuple[int, int], tuple[str, bool]] = {}
    for t in store.trials():
        if t.phase == "task" and t.status == "completed":
            levels = "/".join(v for v in (t.difficulty, t.correctness) if v)
            label = f"{levels or t.task}, {t.mode}"
            last[(t.session_id, t.step)] = (label, bool(t.success))
    counts: dict[str, list[int]] = {}
    for label, ok in last.values():
        n = counts.setdefault(label, [0, 0])
        n[0] += 1
        n[1] += int(ok)
    rows = {p.participant: p.schedule_row for p in store.participants()}
    history = [
        Enrollment(s.participant, withdrawn=s.status == "withdrawn", row=rows.get(s.participant))
        for s in sessions
    ]
    row = next_row(history)
    design = Design.from_protocol(protocol)
    upcoming = [f"{t.position}. {t.task}, {t.mode}" for t in design.row_trials(row)]
    group = protocol.group_for(row).label
    if group:  # a between-subjects design: the group the row belongs to comes first
        upcoming.insert(0, group)
    return StudyProgress(
        planned=protocol.study.participants,
        completed=statuses.count("completed"),
        running=sum(s in ("enrolled", "running") for s in statuses),
        stopped=sum(s in STOPPED for s in statuses),
        conditions=tuple((label, n, ok) for label, (n, ok) in sorted(counts.items())),
        next_row=row,
        next_schedule=tuple(upcoming),
    )


__all__ = ["study_progress"]

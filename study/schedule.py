"""Counterbalanced schedules: Williams Latin squares, the paper's nested scheme, between groups.

A Williams square of ``n`` conditions is a Latin square (each condition once in every position)
that is also balanced for first-order carry-over: every condition immediately follows every
other one equally often. For even ``n`` one square of ``n`` rows does it; for odd ``n`` the square
and its mirror image (each row reversed) together do, ``2n`` rows.

Construction: first row ``0, 1, n-1, 2, n-2, 3, ...``; row ``i`` adds ``i`` to every entry mod n.

A participant's *design row* ``r`` fixes their whole schedule: the task order is Williams row
``r mod R`` (``R`` task rows), and within task ``t`` the modes are done in the order of the
Williams square over the modes, row ``(r div R + t) mod M``. After ``R * M`` participants (one
*cycle*, 8 for the paper's 4 tasks x 2 modes) every task is in every position equally often and
every task is done first in each mode equally often. That is the ``nested`` scheme (each task's
runs back to back). The ``williams`` scheme orders every task x mode condition by one Williams
square over all of them (row ``r mod C``, ``C`` its rows), runs of a task not necessarily together.

Between-subjects groups (``G`` of them) take turns: row ``r`` is in group ``r mod G`` and uses
the within-subjects design row ``r div G``, so one cycle is ``G`` times the within cycle and
fills every group with every order once. Rows are handed out in enrollment order; a withdrawn
participant's row is given to the next enrollment (:func:`next_row`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Protocol as Structural

from study.errors import StudyError

SCHEMES = ("nested", "williams")


class DesignSource(Structural):
    """Anything that names its tasks, modes and between groups in order and its scheme: a loaded
    protocol does (the schedule needs nothing else from it, so it does not import the protocol
    package)."""

    @property
    def task_names(self) -> tuple[str, ...]: ...

    @property
    def mode_names(self) -> tuple[str, ...]: ...

    @property
    def group_names(self) -> tuple[str, ...]: ...

    @property
    def scheme(self) -> str: ...


class ScheduleError(StudyError, ValueError):
    """A schedule cannot be built from the given tasks, modes or enrollment history."""


def williams_square(n: int) -> tuple[tuple[int, ...], ...]:
    """Rows of a Williams design over conditions ``0..n-1`` (``n`` rows if even, ``2n`` if odd)."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ScheduleError(f"williams_square: need a positive number of conditions, got {n!r}")
    first = [0]
    lo, hi = 1, n - 1
    take_lo = True
    while len(first) < n:
        if take_lo:
            first.append(lo)
            lo += 1
        else:
            first.append(hi)
            hi -= 1
        take_lo = not take_lo
    rows = [tuple((c + i) % n for c in first) for i in range(n)]
    if n % 2 == 1 and n > 1:
        rows += [tuple(reversed(r)) for r in rows]
    return tuple(rows)


@dataclass(frozen=True)
class ScheduledTrial:
    """One task trial of a participant's schedule.

    ``position`` is 1-based among the participant's task trials (training excluded); ``run`` is
    1-based among the runs of the same task (1 = first run, 2 = second ...).
    """

    participant: str
    row: int
    position: int
    task: str
    mode: str
    run: int


@dataclass(frozen=True)
class Design:
    """The orders of ``tasks`` x ``modes`` (names, in protocol order) under ``scheme``, for
    ``groups`` between-subjects groups."""

    tasks: tuple[str, ...]
    modes: tuple[str, ...]
    scheme: str = "nested"
    groups: int = 1

    def __post_init__(self) -> None:
        for label, names in (("tasks", self.tasks), ("modes", self.modes)):
            if not names:
                raise ScheduleError(f"Design: need at least one of {label}")
            if len(set(names)) != len(names):
                raise ScheduleError(f"Design: {label} must be distinct, got {names}")
        if self.scheme not in SCHEMES:
            raise ScheduleError(
                f"Design: scheme is one of {', '.join(SCHEMES)}, got {self.scheme!r}"
            )
        if isinstance(self.groups, bool) or not isinstance(self.groups, int) or self.groups < 1:
            raise ScheduleError(f"Design: groups is a positive integer, got {self.groups!r}")

    @classmethod
    def from_protocol(cls, protocol: DesignSource) -> Design:
        """The design of a loaded protocol: its tasks and modes in their declared order."""
        return cls(
            tasks=protocol.task_names,
            modes=protocol.mode_names,
            scheme=protocol.scheme,
            groups=len(protocol.group_names),
        )

    @property
    def task_orders(self) -> tuple[tuple[int, ...], ...]:
        return williams_square(len(self.tasks))

    @property
    def mode_orders(self) -> tuple[tuple[int, ...], ...]:
        return williams_square(len(self.modes))

    @property
    def condition_orders(self) -> tuple[tuple[int, ...], ...]:
        """The ``williams`` scheme's orders over conditions ``task_index * M + mode_index``."""
        return williams_square(len(self.tasks) * len(self.modes))

    @property
    def within_cycle(self) -> int:
        """Design rows that balance the within-subjects orders once."""
        if self.scheme == "williams":
            return len(self.condition_orders)
        return len(self.task_orders) * len(self.mode_orders)

    @property
    def cycle(self) -> int:
        """Participants in one fully balanced cycle: groups x within-subjects orders."""
        return self.groups * self.within_cycle

    @property
    def cycle_parts(self) -> str:
        """What the cycle is made of, in words (for messages)."""
        if self.scheme == "williams":
            within = (
                f"{self.within_cycle} orders of the {len(self.tasks) * len(self.modes)} conditions"
            )
        else:
            within = f"{len(self.task_orders)} task orders x {len(self.mode_orders)} mode orders"
        return within if self.groups == 1 else f"{self.groups} groups x {within}"

    def group(self, row: int) -> int:
        """The between-subjects group (0-based) of design row ``row``."""
        _check_row(row)
        return row % self.groups

    @property
    def trials_per_participant(self) -> int:
        return len(self.tasks) * len(self.modes)

    def task_order(self, row: int) -> tuple[str, ...]:
        """Task names in the order design row ``row`` first does them."""
        _check_row(row)
        if self.scheme == "williams":
            return tuple(dict.fromkeys(t for t, _ in self.conditions(row)))
        orders = self.task_orders
        return tuple(self.tasks[i] for i in orders[(row // self.groups) % len(orders)])

    def mode_order(self, row: int, task: str) -> tuple[str, ...]:
        """Mode names in the order design row ``row`` does them within ``task``."""
        _check_row(row)
        if task not in self.tasks:
            raise ScheduleError(f"no task {task!r}; tasks: {self.tasks}")
        if self.scheme == "williams":
            return tuple(m for t, m in self.conditions(row) if t == task)
        replicate = (row // self.groups) // len(self.task_orders)
        orders = self.mode_orders
        order = orders[(replicate + self.tasks.index(task)) % len(orders)]
        return tuple(self.modes[i] for i in order)

    def conditions(self, row: int) -> tuple[tuple[str, str], ...]:
        """Every ``(task, mode)`` of design row ``row`` in the order they are done."""
        _check_row(row)
        if self.scheme == "nested":
            return tuple((t, m) for t in self.task_order(row) for m in self.mode_order(row, t))
        orders = self.condition_orders
        n_modes = len(self.modes)
        order = orders[(row // self.groups) % len(orders)]
        return tuple((self.tasks[c // n_modes], self.modes[c % n_modes]) for c in order)

    def row_trials(self, row: int, *, participant: str = "") -> tuple[ScheduledTrial, ...]:
        """Every task trial of design row ``row``, in order (``nested``: each task's runs
        back to back); ``run`` counts the runs of the same task so far."""
        trials: list[ScheduledTrial] = []
        runs: dict[str, int] = {}
        for task, mode in self.conditions(row):
            runs[task] = runs.get(task, 0) + 1
            trials.append(
                ScheduledTrial(
                    participant=participant,
                    row=row,
                    position=len(trials) + 1,
                    task=task,
                    mode=mode,
                    run=runs[task],
                )
            )
        return tuple(trials)


def _check_row(row: int) -> None:
    if isinstance(row, bool) or not isinstance(row, int) or row < 0:
        raise ScheduleError(f"design rows are integers >= 0, got {row!r}")


def participant_label(index: int, *, total: int) -> str:
    """``P01`` ... : 1-based, zero-padded to the width of ``total`` (at least two digits)."""
    return f"P{index:0{max(2, len(str(total)))}d}"


def schedule(
    design: Design | DesignSource, *, participants: int, rows: Sequence[int] | None = None
) -> list[ScheduledTrial]:
    """The task trials of ``participants`` participants, enrolled in order, none withdrawn.

    ``rows`` gives each participant's design row (default ``0, 1, 2, ...``).
    """
    if not isinstance(design, Design):
        design = Design.from_protocol(design)
    if isinstance(participants, bool) or not isinstance(participants, int) or participants < 1:
        raise ScheduleError(f"participants must be a positive integer, got {participants!r}")
    if rows is None:
        rows = range(participants)
    if len(rows) != participants:
        raise ScheduleError(f"{participants} participants but {len(rows)} rows")
    out: list[ScheduledTrial] = []
    for i, row in enumerate(rows, start=1):
        out.extend(design.row_trials(row, participant=participant_label(i, total=participants)))
    return out


@dataclass(frozen=True)
class Enrollment:
    """One enrolled participant, in enrollment order: ``row`` None = not recorded (replayed)."""

    participant: str
    withdrawn: bool = False
    row: int | None = None


def assign_rows(history: Iterable[Enrollment | tuple[str, bool]]) -> list[int]:
    """The design row of every enrollment in ``history`` (in order).

    A recorded ``row`` is kept. An unrecorded one is replayed under the rule of
    :func:`next_row`, assuming sessions ran one after another (a participant who withdrew did so
    before the next one enrolled).
    """
    rows: list[int] = []
    seen: list[Enrollment] = []
    participants: set[str] = set()
    for entry in history:
        e = entry if isinstance(entry, Enrollment) else Enrollment(entry[0], bool(entry[1]))
        if e.participant in participants:
            raise ScheduleError(f"participant {e.participant!r} enrolled twice in the history")
        participants.add(e.participant)
        if e.row is not None:
            _check_row(e.row)
        row = e.row if e.row is not None else _next(seen, rows)
        if row in {r for s, r in zip(seen, rows, strict=True) if not s.withdrawn}:
            raise ScheduleError(
                f"participant {e.participant!r}: row {row} is held by an active participant"
            )
        rows.append(row)
        seen.append(e)
    return rows


def next_row(history: Iterable[Enrollment | tuple[str, bool]]) -> int:
    """The design row for the next enrollment, given everyone enrolled so far (in order).

    ``history`` holds :class:`Enrollment` values or ``(participant, withdrawn)`` pairs. The next
    row is the lowest one no active (not withdrawn) participant holds: rows go out 0, 1, 2, ...
    in enrollment order, a withdrawn participant's row goes to the next enrollment, and a row
    skipped by an explicit override is filled later, so the design stays balanced.
    """
    entries = [e if isinstance(e, Enrollment) else Enrollment(e[0], bool(e[1])) for e in history]
    rows = assign_rows(entries)
    return _next(entries, rows)


def _next(entries: Sequence[Enrollment], rows: Sequence[int]) -> int:
    active = {r for e, r in zip(entries, rows, strict=True) if not e.withdrawn}
    row = 0
    while row in active:
        row += 1
    return row

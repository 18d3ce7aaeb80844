"""The design's factors by name: ``[factors]`` and ``[design]`` of a protocol.

Two forms, mixable in one ``[factors]`` table::

    [factors]
    difficulty = ["easy", "hard"]      # short form: within subjects; its levels are set by the
    correctness = ["right", "wrong"]   # [tasks.*] tables (difficulty, correctness) and by
    mode = ["timid", "aggressive"]     # [prediction.<correctness>] and [modes.<mode>] tables

    [factors.mapping]                  # long form: each level says what it sets
    subjects = "between"               # "within" (the default) or "between"
    levels.absolute = { input_mapping = "absolute" }
    levels.relative = { input_mapping = "relative" }

A level may set the task (:data:`TASK_SETTINGS`: the scene, the prediction, the time limit) or
how a run goes (:data:`RUN_SETTINGS`: the arbitration, confidence, robot policy, intent display,
input mapping, added latency). A within factor that sets the task varies *what* is done (crossed with the
other task factors into the tasks); any other within factor varies *how* the robot helps
(crossed with ``mode`` into the runs done of every task). A between factor sets run settings for
every run of the participants assigned to its level. ``mode`` (the arbitration) is always a
within factor. ``[design] scheme`` names the counterbalancing (``study.schedule``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from study.protocol.fields import Table, join_key

SUBJECTS = ("within", "between")
TASK_SETTINGS = ("scene", "prediction", "time_limit_s")
"""What a level may set about the task itself."""
RUN_SETTINGS = ("arbitration", "confidence", "policy", "intent", "input_mapping", "latency_s")
"""What a level may set about how a run goes (a between factor sets these only); ``latency_s``
is added latency: the participant's commands act that much later (``app.teleop.delayed_input``)."""
MAX_LATENCY_S = 2.0
SCHEMES = ("nested", "williams")
"""``nested``: the paper's (Williams task orders, each task's runs back to back in a Williams
mode order); ``williams``: one Williams square over every task x run condition."""
MODE_FACTOR = "mode"
LevelCheck = Callable[[str, str], None]
"""Checks a level name (the name, its key path); raises a ``ProtocolError``."""


@dataclass(frozen=True)
class Factor:
    """One declared factor: its levels in order, ``within`` or ``between`` subjects, and what
    each level sets (``settings[level]``, empty for a short-form factor)."""

    name: str
    levels: tuple[str, ...]
    subjects: str = "within"
    settings: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    short: bool = True

    @property
    def between(self) -> bool:
        return self.subjects == "between"

    @property
    def sets_task(self) -> bool:
        """Whether some level sets the task (scene, prediction or time limit)."""
        return any(k in TASK_SETTINGS for s in self.settings.values() for k in s)


def read_design(t: Table) -> str:
    """``[design] scheme``: the counterbalancing scheme (default ``nested``)."""
    t.only("scheme")
    scheme = t.choice("scheme", SCHEMES, "nested")
    t.close(allowed="scheme")
    return scheme


def read_factors(t: Table, *, level_name: LevelCheck) -> tuple[Factor, ...]:
    """Every factor of ``[factors]`` in file order; ``level_name(table, key)`` checks a name.

    Raises a ``ProtocolError`` naming the key for an unknown setting, a between factor that
    sets the task, a ``mode`` declared between subjects, or a factor with fewer than 1 level.
    """
    factors: list[Factor] = []
    for name in list(t.keys()):
        if isinstance(t.data[name], Mapping):
            factors.append(_long(t.table(name), name, level_name=level_name))
        else:
            factors.append(Factor(name=name, levels=_short_levels(t, name, level_name)))
    t.close(allowed="factor names")
    names = [f.name for f in factors]
    if MODE_FACTOR not in names:
        raise t.value_error(
            MODE_FACTOR,
            "declare the factor mode (how the robot arbitrates), even with a single level",
        )
    return tuple(factors)


def _short_levels(t: Table, name: str, level_name: LevelCheck) -> tuple[str, ...]:
    levels = t.strings(name)
    for i, level in enumerate(levels):
        level_name(level, join_key(t.where(name), i))
    return levels


def _long(t: Table, name: str, *, level_name: LevelCheck) -> Factor:
    t.only("subjects", "levels")
    subjects = t.choice("subjects", SUBJECTS, "within")
    raw = t.raw("levels")
    if isinstance(raw, list):
        levels = _short_levels(t, "levels", level_name)
        settings: dict[str, Mapping[str, Any]] = {level: {} for level in levels}
    else:
        table = t.table("levels")
        settings = {}
        for level, sub in table.tables():
            level_name(level, sub.where())
            settings[level] = MappingProxyType(_settings(sub))
        table.close(allowed="one table per level")
        levels = tuple(settings)
        if not levels:
            raise t.value_error("levels", "give the factor at least one level")
    t.close(allowed="subjects, levels")
    factor = Factor(
        name=name,
        levels=levels,
        subjects=subjects,
        settings=MappingProxyType(settings),
        short=False,
    )
    if factor.between and name == MODE_FACTOR:
        raise t.value_error("subjects", "mode is done within subjects (every run in each mode)")
    if factor.between and factor.sets_task:
        raise t.value_error(
            "levels",
            f"a between-subjects factor sets how runs go ({', '.join(RUN_SETTINGS)}), not the"
            f" task ({', '.join(TASK_SETTINGS)}): make {name} a within factor, or move the"
            " task setting to [tasks] or a within factor",
        )
    return factor


def _settings(sub: Table) -> dict[str, Any]:
    allowed = (*TASK_SETTINGS, *RUN_SETTINGS)
    sub.only(*allowed)
    out = {key: sub.raw(key) for key in allowed if key in sub}
    sub.close(allowed=", ".join(allowed))
    return out

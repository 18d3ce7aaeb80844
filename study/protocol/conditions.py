"""Conditions from the declared factors: the tasks, the modes and the between-subjects groups.

A condition is a task done in a mode by a participant of a group; its settings are the union of
what its parts set. Tasks are ``[tasks.*]`` (each naming a level of every short-form task
factor) crossed with the levels of the long-form factors that set the task; modes are the levels
of ``mode`` crossed with the other within factors that set how runs go; groups are the crossed
levels of the between factors. Two parts of one condition that set the same key to different
values are an error naming both (:class:`ConditionConflictError`), found at load time.
"""

from __future__ import annotations

import difflib
import itertools
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from app.teleop.participant_input import INPUT_MAPPINGS
from study.protocol.components import component
from study.protocol.errors import (
    ConditionConflictError,
    ProtocolTypeError,
    ProtocolValueError,
    UndefinedReferenceError,
    UnknownKeyError,
)
from study.protocol.factors import MAX_LATENCY_S, MODE_FACTOR, TASK_SETTINGS, Factor
from study.protocol.fields import Table, check_number
from study.protocol.model import INTENT_DISPLAYS, Control, Group, Mode, Task
from study.protocol.protocol import TRAINING_MODE

Source = tuple[str, Mapping[str, Any]]
"""Where settings come from (a key path such as ``factors.goals.levels.four``) and what it sets."""
NameCheck = Callable[..., None]
"""Checks a name (the name, its key path, ``what=`` it names); raises a ``ProtocolError``."""


def merge(sources: Iterable[Source], *, file: str) -> dict[str, tuple[str, Any]]:
    """``{key: (where, value)}`` over ``sources``; two sources setting one key differently
    raise :class:`ConditionConflictError` naming both."""
    out: dict[str, tuple[str, Any]] = {}
    for where, settings in sources:
        for key, value in settings.items():
            if key in out and out[key][1] != value:
                first, before = out[key]
                raise ConditionConflictError(
                    f"{first} sets {key} = {before!r} and {where} sets {key} = {value!r}; a"
                    " condition combines both, so only one of them may set it",
                    file=file,
                    key=where,
                )
            out[key] = (where, value)
    return out


@dataclass
class Conditions:
    """Builds the conditions of one protocol file; ``root`` is its top-level table."""

    root: Table
    factors: tuple[Factor, ...]
    scenes: Mapping[str, Any]
    control: Control
    check_name: NameCheck

    @property
    def file(self) -> str:
        return str(self.root.file)

    def within_run_factors(self) -> list[Factor]:
        """``mode`` first, then every other within factor that does not set the task."""
        mode = [f for f in self.factors if f.name == MODE_FACTOR]
        rest = [
            f
            for f in self.factors
            if f.name != MODE_FACTOR and not f.between and not f.short and not f.sets_task
        ]
        return mode + rest

    # -- tasks ------------------------------------------------------------------------------
    def tasks(self, predictions: Mapping[str, Any]) -> tuple[Task, ...]:
        """Every task: ``[tasks.*]`` crossed with the long-form task factors' levels."""
        crossed = [f for f in self.factors if not f.short and f.sets_task]
        bases = self._base_tasks()
        out: list[Task] = []
        for base_name, base_levels, base_settings in bases:
            for combo in itertools.product(*(f.levels for f in crossed)):
                name = "-".join([n for n in (base_name,) if n] + list(combo))
                sources: list[Source] = [(f"tasks.{base_name}", base_settings)] if base_name else []
                sources += [
                    (f"factors.{f.name}.levels.{lv}", f.settings[lv])
                    for f, lv in zip(crossed, combo, strict=True)
                ]
                levels = {
                    **base_levels,
                    **{f.name: lv for f, lv in zip(crossed, combo, strict=True)},
                }
                out.append(self._task(name, levels, merge(sources, file=self.file), predictions))
        return tuple(out)

    def _short_task_factors(self) -> list[Factor]:
        return [f for f in self.factors if f.short and f.name != MODE_FACTOR]

    def _base_tasks(self) -> list[tuple[str, dict[str, str], dict[str, Any]]]:
        """``(name, levels, settings)`` of every ``[tasks.*]`` table (one nameless base task
        when there is none and no short-form factor needs them)."""
        short = self._short_task_factors()
        if "tasks" not in self.root:
            if short:
                raise self.root.value_error(
                    "tasks",
                    f"factors.{short[0].name} is given as a list of levels, which [tasks.*]"
                    " tables set: define them, or give each level its settings"
                    f" ([factors.{short[0].name}] levels.<level> = {{ scene = ... }})",
                )
            if not any(f.sets_task for f in self.factors):
                raise self.root.value_error(
                    "tasks", "define [tasks.*], or a factor whose levels set the scene"
                )
            return [("", {}, {})]
        t = self.root.table("tasks")
        keys = ("scene", "time_limit_s", "prediction", *(f.name for f in short))
        bases: list[tuple[str, dict[str, str], dict[str, Any]]] = []
        cells: dict[tuple[str, ...], str] = {}
        for name, sub in t.tables():
            self.check_name(name, sub.where(), what="task names")
            self._unnamed_factor(sub, keys, short)
            sub.only(*keys)
            levels = {f.name: self._level_ref(sub, f) for f in short}
            settings = {k: sub.raw(k) for k in ("scene", "time_limit_s", "prediction") if k in sub}
            sub.close(allowed=", ".join(keys))
            cell = tuple(levels.values())
            if short and cell in cells:
                shown = " and ".join(f.name for f in short)
                raise t.value_error(
                    name, f"same {shown} as task {cells[cell]!r}; each combination is one task"
                )
            cells[cell] = name
            bases.append((name, levels, settings))
        for combo in itertools.product(*(f.levels for f in short)):
            if combo not in cells:
                said = " and ".join(
                    f"{f.name} = {lv!r}" for f, lv in zip(short, combo, strict=True)
                )
                raise UndefinedReferenceError(
                    f"no task has {said}; the design crosses every level of"
                    f" {', '.join(f.name for f in short)}",
                    file=self.file,
                    key=t.where(),
                )
        if not bases:
            raise t.value_error("", "define at least one task")
        return bases

    def _unnamed_factor(self, sub: Table, keys: Sequence[str], short: Sequence[Factor]) -> None:
        """A task key that is no factor, beside a short-form factor it misspells: the factor's
        declaration is the typo (``dificulty = [...]`` against tasks naming ``difficulty``)."""
        for key in sub.data:
            if key in keys:
                continue
            close = difflib.get_close_matches(key, [f.name for f in short], n=1, cutoff=0.6)
            if close:
                raise UnknownKeyError(
                    f"unknown key {close[0]!r}: no task names it (the tasks name {key!r});"
                    " check the spelling",
                    file=self.file,
                    key=f"factors.{close[0]}",
                )

    def _level_ref(self, sub: Table, factor: Factor) -> str:
        value = sub.string(factor.name)
        if value not in factor.levels:
            raise UndefinedReferenceError(
                f"{value!r} is not a level of factors.{factor.name} ({', '.join(factor.levels)})",
                file=self.file,
                key=sub.where(factor.name),
            )
        return value

    def _task(
        self,
        name: str,
        levels: dict[str, str],
        merged: dict[str, tuple[str, Any]],
        predictions: Mapping[str, Any],
    ) -> Task:
        if "scene" not in merged:
            raise self.root.value_error(
                f"tasks.{name}" if "tasks" in self.root else "factors",
                f"task {name!r} has no scene: set scene in its [tasks] table or in a level"
                " of a factor that sets the task",
            )
        where, scene = merged["scene"]
        if not isinstance(scene, str) or scene not in self.scenes:
            raise UndefinedReferenceError(
                f"scene {scene!r} is not defined; defined scenes: {', '.join(self.scenes)}",
                file=self.file,
                key=f"{where}.scene",
            )
        limit = self.control.time_limit_s
        if "time_limit_s" in merged:
            where_t, value = merged["time_limit_s"]
            limit = check_number(
                Table({}, file=self.file, key=where_t),
                "time_limit_s",
                value,
                minimum=1.0,
                maximum=3600.0,
            )
        return Task(
            name=name,
            scene=scene,
            time_limit_s=limit,
            prediction=self._prediction(name, levels, merged, predictions),
            levels=MappingProxyType(levels),
        )

    def _prediction(
        self,
        name: str,
        levels: Mapping[str, str],
        merged: dict[str, tuple[str, Any]],
        predictions: Mapping[str, Any],
    ) -> Mapping[str, Any]:
        """The task's predictor: what a level or its [tasks] table sets (a [prediction.<name>]
        name or an inline table), else the paper's [prediction.<correctness level>]."""
        if "prediction" in merged:
            where, value = merged["prediction"]
            if isinstance(value, Mapping):
                table = Table(value, file=self.file, key=f"{where}.prediction")
                return MappingProxyType(component(table, "prediction"))
            if isinstance(value, str) and value in predictions:
                return predictions[value]
            raise UndefinedReferenceError(
                f"prediction {value!r} is not defined; give a [prediction.<name>] name"
                f" ({', '.join(predictions) or 'none defined'}) or an inline table",
                file=self.file,
                key=f"{where}.prediction",
            )
        level = levels.get("correctness")
        if level is not None and level in predictions:
            return predictions[level]
        correctness = next((f.levels for f in self.factors if f.name == "correctness"), ())
        raise UndefinedReferenceError(
            f"missing: correctness level {level!r} needs a [prediction.{level}] table"
            + _misspelt("prediction", predictions, level, correctness)
            if level is not None
            else f"task {name!r} has no prediction: set prediction in its [tasks] table or in"
            " a level of a factor that sets the task",
            file=self.file,
            key=f"prediction.{level}" if level is not None else f"tasks.{name}",
        )

    # -- modes ------------------------------------------------------------------------------
    def modes(self) -> tuple[Mode, ...]:
        """``mode``'s levels crossed with the other within factors that set how runs go."""
        factors = self.within_run_factors()
        mode_sources = self._mode_sources(factors[0])
        out: list[Mode] = []
        for combo in itertools.product(*(f.levels for f in factors)):
            sources = [mode_sources[combo[0]]]
            sources += [
                (f"factors.{f.name}.levels.{lv}", f.settings[lv])
                for f, lv in zip(factors[1:], combo[1:], strict=True)
            ]
            levels = {f.name: lv for f, lv in zip(factors, combo, strict=True)}
            out.append(self._mode("-".join(combo), levels, merge(sources, file=self.file)))
        return tuple(out)

    def _mode_sources(self, mode: Factor) -> dict[str, Source]:
        """What each level of ``mode`` sets: its ``[modes.<level>]`` table (the short form) or
        its own settings (the long form)."""
        if TRAINING_MODE in mode.levels:
            raise self.root.value_error(
                "factors.mode", f"{TRAINING_MODE!r} is reserved for training runs"
            )
        if not mode.short:
            if "modes" in self.root:
                raise self.root.value_error(
                    "modes",
                    "factors.mode sets its levels itself; remove [modes] or the levels' settings",
                )
            return {lv: (f"factors.mode.levels.{lv}", mode.settings[lv]) for lv in mode.levels}
        t = self.root.table("modes")
        out: dict[str, Source] = {}
        for level in mode.levels:
            if level not in t:
                raise UndefinedReferenceError(
                    f"missing: mode {level!r} (factors.mode) needs a [modes.{level}] table"
                    + _misspelt(t.key, t.data, level, mode.levels),
                    file=self.file,
                    key=t.where(level),
                )
            sub = t.table(level)
            sub.only("arbitration", "confidence", "intent")
            out[level] = (f"modes.{level}", {k: sub.raw(k) for k in sub.data})
        t.close(allowed=f"the mode levels {', '.join(mode.levels)}")
        return out

    def _mode(self, name: str, levels: dict[str, str], merged: dict[str, tuple[str, Any]]) -> Mode:
        if "arbitration" not in merged:
            raise UndefinedReferenceError(
                f"mode {name!r} has no arbitration: set it in [modes.{levels[MODE_FACTOR]}] or"
                " in a level of factors.mode",
                file=self.file,
                key=f"modes.{levels[MODE_FACTOR]}",
            )
        run = self.run_settings(merged)
        arbitration = run["arbitration"]
        if run.get("intent", "none") != "none" and arbitration["kind"] == "none":
            raise ProtocolValueError(
                "an unassisted mode has no intent to show",
                file=self.file,
                key=f"{merged['intent'][0]}.intent",
            )
        return Mode(
            name=name,
            arbitration=None if arbitration["kind"] == "none" else arbitration,
            confidence=run.get("confidence"),
            intent=run.get("intent", "none"),
            levels=MappingProxyType(levels),
            policy=run.get("policy"),
            input_mapping=run.get("input_mapping"),
            latency_s=run.get("latency_s"),
        )

    def run_settings(self, merged: Mapping[str, tuple[str, Any]]) -> dict[str, Any]:
        """Checked run settings: blending tables through their specification, choices against
        their values; a task setting here is an error."""
        out: dict[str, Any] = {}
        for key, (where, value) in merged.items():
            at = f"{where}.{key}"
            if key in TASK_SETTINGS:
                raise ProtocolValueError(
                    f"{key} sets the task; a mode or between-subjects level sets how runs go",
                    file=self.file,
                    key=at,
                )
            if key in ("arbitration", "confidence", "policy"):
                if not isinstance(value, Mapping):
                    raise ProtocolTypeError(
                        f"expected a table, got {value!r}", file=self.file, key=at
                    )
                out[key] = MappingProxyType(component(Table(value, file=self.file, key=at), key))
            elif key == "latency_s":
                out[key] = check_number(
                    Table({}, file=self.file, key=where),
                    key,
                    value,
                    minimum=0.0,
                    maximum=MAX_LATENCY_S,
                )
            else:
                choices = INTENT_DISPLAYS if key == "intent" else INPUT_MAPPINGS
                if value not in choices:
                    raise ProtocolValueError(
                        f"{value!r} is not one of {', '.join(choices)}", file=self.file, key=at
                    )
                out[key] = value
        return out

    # -- groups -----------------------------------------------------------------------------
    def groups(self, modes: Sequence[Mode]) -> tuple[Group, ...]:
        """The crossed levels of the between factors (one empty group if there are none);
        each group's settings are checked against every mode's for conflicts."""
        between = [f for f in self.factors if f.between]
        out: list[Group] = []
        for combo in itertools.product(*(f.levels for f in between)):
            sources = [
                (f"factors.{f.name}.levels.{lv}", f.settings[lv])
                for f, lv in zip(between, combo, strict=True)
            ]
            merged = merge(sources, file=self.file)
            for m in modes:
                merge([*self._mode_as_sources(m), *sources], file=self.file)
            out.append(
                Group(
                    name="-".join(combo),
                    levels=MappingProxyType(
                        {f.name: lv for f, lv in zip(between, combo, strict=True)}
                    ),
                    settings=MappingProxyType(self.run_settings(merged)),
                )
            )
        return tuple(out)

    def _mode_as_sources(self, mode: Mode) -> list[Source]:
        """What ``mode`` sets, as sources named after its levels (for conflict messages)."""
        label = " x ".join(f"factors.{f}.levels.{lv}" for f, lv in mode.levels.items())
        settings: dict[str, Any] = {}
        for key in ("confidence", "policy", "input_mapping", "latency_s"):
            value = getattr(mode, key)
            if value is not None:
                settings[key] = _plain(value)
        if mode.intent != "none":
            settings["intent"] = mode.intent
        settings["arbitration"] = (
            _plain(mode.arbitration) if mode.arbitration is not None else {"kind": "none"}
        )
        return [(f"mode {mode.name!r} ({label})", settings)]


def _plain(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _misspelt(table: str, keys: Iterable[str], level: str, levels: Sequence[str]) -> str:
    """``"; is [x.levl] a misspelling of it?"`` when ``table`` has a key close to ``level``."""
    spare = [str(k) for k in keys if k not in levels]
    close = difflib.get_close_matches(level, spare, n=1, cutoff=0.6)
    return f"; is [{table}.{close[0]}] a misspelling of it?" if close else ""

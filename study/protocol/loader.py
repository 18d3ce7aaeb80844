"""``load_protocol(path) -> Protocol``: read a TOML study definition and validate all of it.

Checks, each failing with a typed :class:`~study.protocol.errors.ProtocolError` that names the
file, the key path and the problem: TOML syntax and duplicate keys; unknown keys at every level;
types and ranges; references (a task's scene, a factor level, a questionnaire item or scale);
the declared factors and the conditions built from them (``study.protocol.factors``,
``study.protocol.conditions``: every cell of the task factors once, one mode table per mode
level, no two levels of one condition setting one value differently); a sample of whole balanced
cycles; anchors matching the questionnaire's number of points; and blinding (no
participant-facing text contains a condition word).
"""

from __future__ import annotations

import hashlib
import json
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import app
from app.files import InputFileError, read_bytes_file
from app.robot.errors import SceneError
from app.robot.scene_spec import SceneSpec
from app.teleop.participant_input import INPUT_MAPPINGS
from app.trial.config import ON_KNOCK, TrialConfig
from study.protocol.components import build_check, component
from study.protocol.conditions import Conditions
from study.protocol.errors import (
    ProtocolError,
    ProtocolSyntaxError,
    ProtocolValueError,
    UndefinedReferenceError,
)
from study.protocol.factors import read_design, read_factors
from study.protocol.fields import Table
from study.protocol.items import read_questionnaire
from study.protocol.model import Control, Group, Mode, StudyInfo, Task, Training
from study.protocol.participant_texts import check_blinding, read_texts
from study.protocol.protocol import Protocol
from study.schedule import Design

SCHEMA = 1
MAX_PROTOCOL_BYTES = 2**20
"""Largest protocol file read (the paper's is about 12 KB)."""
MAX_NESTING = 32
"""Deepest nesting of arrays and inline tables a protocol may have (the paper's has 3).

Python's TOML parser recurses once per level, so a few thousand ``[`` would end in a
``RecursionError`` (or worse, in code that walks the parsed value); the text is scanned first."""
_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")
_CONTROL_OPTIONS: dict[str, tuple[tuple[str, ...], str]] = {
    "on_knock": (ON_KNOCK, "reset"),
    "input_mapping": (INPUT_MAPPINGS, "absolute"),
}
"""Optional ``[control]`` keys with a fixed set of values: (the values, the default)."""
_TOP_LEVEL = (
    "schema",
    "study",
    "control",
    "design",
    "factors",
    "tasks",
    "prediction",
    "confidence",
    "policy",
    "modes",
    "training",
    "scenes",
    "consent",
    "debrief",
    "instructions",
    "questionnaire",
)


def load_protocol(path: str | Path) -> Protocol:
    """Load and validate the protocol at ``path``; raises a ``ProtocolError`` subclass. Only a
    regular file of at most ``MAX_PROTOCOL_BYTES`` is read."""
    path = Path(path)
    try:
        data = read_bytes_file(path, max_bytes=MAX_PROTOCOL_BYTES, what="protocol file")
    except InputFileError as e:
        raise ProtocolError(f"cannot read the file: it {e.problem}", file=path, key="") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ProtocolSyntaxError(
            f"not UTF-8 text (byte offset {e.start}); re-save it as UTF-8", file=path, key=""
        ) from None
    return parse_protocol(text, path=path)


def parse_protocol(text: str, *, path: str | Path = "<string>") -> Protocol:
    """Validate protocol ``text``; ``path`` is used in error messages and kept on the result."""
    _check_nesting(text, path)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise _syntax_error(e, text, path) from None
    except RecursionError:  # not reachable after _check_nesting; kept as a typed last resort
        raise ProtocolSyntaxError(
            f"values are nested too deeply to read (more than {MAX_NESTING} levels)",
            file=path,
            key="",
        ) from None
    return _Loader(raw, Path(path), source=text).protocol()


def nesting_depth(text: str, *, stop_above: int | None = None) -> tuple[int, int]:
    """The deepest nesting of ``[``/``{`` in TOML ``text`` outside strings and comments, and the
    1-based line where it is first reached; stops scanning once ``stop_above`` is exceeded.

    Table headers (``[a]``, ``[[a]]``) count as one or two levels, which only matters near the
    limit. The scan is a single pass without recursion, so any input is safe to measure."""
    depth = deepest = 0
    deepest_line = line = 1
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
        elif c == "#":
            end = text.find("\n", i)
            i = n if end < 0 else end
            continue
        elif c in "\"'":
            i, line = _past_string(text, i, line)
            continue
        elif c in "[{":
            depth += 1
            if depth > deepest:
                deepest, deepest_line = depth, line
                if stop_above is not None and deepest > stop_above:
                    break
        elif c in "]}":
            depth = max(depth - 1, 0)
        i += 1
    return deepest, deepest_line


def _past_string(text: str, i: int, line: int) -> tuple[int, int]:
    """The index just past the TOML string opening at ``text[i]`` (one-line or triple-quoted,
    basic or literal) and the line count after it; an unterminated one-line string ends at its
    line's end, for the parser to report."""
    c, n = text[i], len(text)
    quote = c * 3 if text.startswith(c * 3, i) else c
    j = i + len(quote)
    while j < n and not text.startswith(quote, j):
        if c == '"' and text[j] == "\\":
            j += 1  # skip the escaped character
        elif text[j] == "\n":
            if len(quote) == 1:
                break
            line += 1
        j += 1
    while len(quote) == 3 and text.startswith(c, j + 3):  # """a"""" ends in a quote
        j += 1
    return j + len(quote), line


def _check_nesting(text: str, path: str | Path) -> None:
    deepest, line = nesting_depth(text, stop_above=MAX_NESTING)
    if deepest > MAX_NESTING:
        raise ProtocolSyntaxError(
            f"arrays or inline tables are nested more than {MAX_NESTING} levels deep (the "
            "limit this reader accepts; a study definition needs 3 or 4); flatten the value",
            file=path,
            key=f"line {line}",
        )


def content_hash(raw: Mapping[str, Any]) -> str:
    """sha256 of the canonical JSON form of a parsed protocol (sorted keys, no whitespace)."""
    canonical = json.dumps(
        raw, sort_keys=True, separators=(",", ":"), ensure_ascii=False, default=str
    )
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def _syntax_error(e: tomllib.TOMLDecodeError, text: str, path: str | Path) -> ProtocolSyntaxError:
    message = str(e)
    m = re.search(r"\(at line (\d+), column \d+\)", message)
    key = ""
    if m:
        line_no = int(m.group(1))
        lines = text.splitlines()
        line = lines[line_no - 1].strip() if 0 < line_no <= len(lines) else ""
        key = f"line {line_no}"
        name = line.split("=", 1)[0].strip().strip("[]").strip() if line else ""
        if name:
            key += f" ({name})"
    if "overwrite" in message or "twice" in message:
        problem = f"a key or table is defined twice; remove the duplicate ({message})"
    else:
        problem = f"invalid TOML: {message}"
    return ProtocolSyntaxError(problem, file=path, key=key)


class _Loader:
    def __init__(self, raw: dict[str, Any], path: Path, *, source: str) -> None:
        self.raw = raw
        self.path = path
        self.source = source
        self.root = Table(raw, file=path)

    def error(self, cls: type[ProtocolError], key: str, problem: str) -> ProtocolError:
        return cls(problem, file=self.path, key=key)

    def protocol(self) -> Protocol:
        root = self.root
        root.only(*_TOP_LEVEL)
        schema = root.integer("schema")
        if schema != SCHEMA:
            raise root.value_error("schema", f"this software reads schema {SCHEMA}, got {schema}")
        study = self._study(root.table("study"))
        control = self._control(root.table("control"))
        scheme = read_design(root.table("design")) if "design" in root else "nested"
        declared = read_factors(root.table("factors"), level_name=self._check_name)
        scenes = self._scenes(root.table("scenes"))
        prediction = self._prediction(root.table("prediction")) if "prediction" in root else {}
        conditions = Conditions(root, declared, scenes, control, self._check_name)
        tasks = conditions.tasks(prediction)
        modes = conditions.modes()
        groups = conditions.groups(modes)
        confidence = component(root.table("confidence"), "confidence")
        policy = component(root.table("policy"), "policy")
        training = self._training(root.table("training"), scenes, control)
        design = Design(
            tasks=tuple(t.name for t in tasks),
            modes=tuple(m.name for m in modes),
            scheme=scheme,
            groups=len(groups),
        )
        self._check_sample_size(study, design)
        questionnaire = read_questionnaire(
            root.table("questionnaire"),
            n_modes=len(modes) if scheme == "nested" else 0,
            n_tasks=len(tasks) if scheme == "nested" else design.trials_per_participant,
        )
        self._build_checks(
            tasks, scenes, prediction, confidence, policy, modes, groups, training, control
        )
        texts = read_texts(root, questionnaire=questionnaire)
        root.close(allowed=", ".join(_TOP_LEVEL))
        protocol = Protocol(
            path=self.path,
            schema=schema,
            study=study,
            control=control,
            declared=declared,
            scheme=scheme,
            tasks=tasks,
            modes=modes,
            groups=groups,
            prediction=MappingProxyType(prediction),
            confidence=MappingProxyType(confidence),
            policy=MappingProxyType(policy),
            training=training,
            scenes=MappingProxyType(scenes),
            questionnaire=questionnaire,
            texts=texts,
            content_hash=content_hash(self.raw),
            software_version=app.__version__,
            source=self.source,
        )
        check_blinding(protocol)
        return protocol

    # -- sections ---------------------------------------------------------------------------
    def _study(self, t: Table) -> StudyInfo:
        t.only("id", "title", "version", "description", "participants")
        info = StudyInfo(
            id=self._name(t, "id"),
            title=t.string("title"),
            version=t.string("version"),
            description=t.string("description", "", nonempty=False),
            participants=t.integer("participants", None, minimum=1, maximum=100_000)
            if "participants" in t
            else None,
        )
        return info

    def _check_sample_size(self, study: StudyInfo, design: Design) -> None:
        n = study.participants
        if n is not None and n % design.cycle:
            raise self.error(
                ProtocolValueError,
                "study.participants",
                f"{n} participants do not fill whole balanced cycles of {design.cycle}"
                f" ({design.cycle_parts}); use a multiple of {design.cycle}",
            )

    def _control(self, t: Table) -> Control:
        keys = ("rate_hz", "physics_dt", "time_limit_s", "lift_height_m", *_CONTROL_OPTIONS)
        t.only(*keys)
        control = Control(
            rate_hz=t.number("rate_hz", minimum=10.0, maximum=1000.0),
            physics_dt=t.number("physics_dt", minimum=1e-4, maximum=0.01),
            time_limit_s=t.number("time_limit_s", minimum=1.0, maximum=3600.0),
            lift_height_m=t.number("lift_height_m", minimum=0.005, maximum=0.3),
            **{key: t.choice(key, *choices) for key, choices in _CONTROL_OPTIONS.items()},
        )
        t.close(allowed=", ".join(keys))
        ratio = 1.0 / (control.rate_hz * control.physics_dt)
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise t.value_error(
                "physics_dt",
                f"{control.physics_dt} s must divide the control period 1/rate_hz ="
                f" {1.0 / control.rate_hz} s a whole number of times",
            )
        return control

    def _name(self, t: Table, key: str) -> str:
        value = t.string(key)
        self._check_name(value, t.where(key))
        return value

    def _check_name(self, value: str, key: str, *, what: str = "names") -> None:
        if not _NAME.match(value):
            raise self.error(
                ProtocolValueError,
                key,
                f"{value!r}: {what} must be lower-case letters, digits, '_' or '-'"
                " (at most 32, starting with a letter)",
            )

    def _scenes(self, t: Table) -> dict[str, Any]:
        scenes: dict[str, Any] = {}
        for name, sub in t.tables():
            where = sub.where()
            try:
                scenes[name] = SceneSpec.from_dict(sub.data, where=where)
            except SceneError as e:
                key, _, problem = str(e).partition(": ")
                if not problem:
                    key, problem = where, str(e)
                raise self.error(ProtocolValueError, key, problem) from None
        if not scenes:
            raise t.value_error("", "define at least one scene")
        return scenes

    def _scene_ref(self, t: Table, key: str, scenes: Mapping[str, Any]) -> str:
        name = t.string(key)
        if name not in scenes:
            raise self.error(
                UndefinedReferenceError,
                t.where(key),
                f"scene {name!r} is not defined; defined scenes: {', '.join(scenes)}",
            )
        return name

    def _prediction(self, t: Table) -> dict[str, Any]:
        """``[prediction.<name>]`` tables, each checked against its kind's specification; a
        task uses one by name (the paper's: by its correctness level)."""
        return {name: MappingProxyType(component(sub, "prediction")) for name, sub in t.tables()}

    def _build_checks(
        self,
        tasks: tuple[Task, ...],
        scenes: Mapping[str, Any],
        prediction: Mapping[str, Any],
        confidence: Mapping[str, Any],
        policy: Mapping[str, Any],
        modes: tuple[Mode, ...],
        groups: tuple[Group, ...],
        training: Training,
        control: Control,
    ) -> None:
        """Build every blending table once with app.blending, in the scenes it will run in."""
        file = str(self.path)
        named = {id(table): f"prediction.{name}" for name, table in prediction.items()}
        runs = [
            (named.get(id(t.prediction), f"tasks.{t.name}.prediction"), t.prediction, t.scene)
            for t in tasks
        ]
        runs.append(("training.prediction", training.prediction, training.scene))
        for where, cfg, scene_name in runs:
            scene = scenes[scene_name]
            build_check(
                "prediction",
                cfg,
                where=where,
                file=file,
                goals=len(scene.objects),
                target=scene.target_index,
                rate_hz=control.rate_hz,
            )
        tables: list[tuple[str, str, Mapping[str, Any] | None]] = [
            ("confidence", "confidence", confidence),
            ("policy", "policy", policy),
        ]
        for m in modes:
            tables += [
                (role, f"modes.{m.name}.{role}", getattr(m, role))
                for role in ("arbitration", "confidence", "policy")
            ]
        for g in groups:
            tables += [
                (role, f"groups.{g.name}.{role}", g.settings.get(role))
                for role in ("confidence", "policy")
            ]
        for role, where, cfg in tables:
            if cfg is not None:
                build_check(role, cfg, where=where, file=file, rate_hz=control.rate_hz)

    def _training(self, t: Table, scenes: Mapping[str, Any], control: Control) -> Training:
        t.only("runs", "scene", "time_limit_s", "prediction")
        prediction = (
            component(t.table("prediction"), "prediction")
            if "prediction" in t
            else {"kind": "oracle"}
        )
        training = Training(
            runs=t.integer("runs", minimum=1, maximum=20),
            scene=self._scene_ref(t, "scene", scenes),
            time_limit_s=t.number(
                "time_limit_s", control.time_limit_s, minimum=1.0, maximum=3600.0
            ),
            prediction=MappingProxyType(prediction),
        )
        t.close(allowed="runs, scene, time_limit_s, prediction")
        return training


def trial_config_from_protocol(
    path: str | Path, task: str, mode: str, *, time_limit_s: float | None = None
) -> TrialConfig:
    """The configuration of ``task`` in ``mode`` of the protocol at ``path``
    (:meth:`Protocol.config_for`: ``mode="none"`` unassisted, ``task="training"``)."""
    return load_protocol(path).config_for(task, mode, time_limit_s=time_limit_s)

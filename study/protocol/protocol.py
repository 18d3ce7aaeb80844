"""``Protocol``: one validated study definition, and what the engine, server and analysis ask of it.

Built by :func:`study.protocol.load_protocol`; immutable. Condition names (task, difficulty,
correctness and mode levels) are for the experimenter and the data only: participant-facing text
comes from :meth:`Protocol.describe_trial`, :meth:`Protocol.describe_training` and
:attr:`Protocol.texts`, which are checked on load never to contain a condition word.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.trial.config import TrialConfig
from study.protocol.blinding import blinded_words
from study.protocol.errors import ConditionError
from study.protocol.factors import Factor
from study.protocol.model import Control, Group, Mode, StudyInfo, Task, Texts, Training
from study.protocol.questionnaire import Questionnaire

if TYPE_CHECKING:
    from app.robot.scene_spec import SceneSpec

TRAINING_MODE = "none"
"""The ``mode`` recorded for unassisted training runs."""


@dataclass(frozen=True, eq=False)
class Protocol:
    """A study: factors, tasks, modes, blending settings, scenes, questionnaire and texts.

    ``content_hash`` is the sha256 of the file's canonical content (key order and formatting do
    not matter); ``software_version`` is ``app.__version__`` at load time. ``source`` is the TOML
    text it was parsed from: the store keeps it (keyed by ``content_hash``), so the exact protocol
    a study ran with can be rebuilt from its store (:func:`study.protocol.protocol_from_store`).
    """

    path: Path
    schema: int
    study: StudyInfo
    control: Control
    declared: tuple[Factor, ...]
    scheme: str  # counterbalancing: "nested" (the paper's) or "williams" (study.schedule)
    tasks: tuple[Task, ...]
    modes: tuple[Mode, ...]
    groups: tuple[Group, ...]  # between-subjects cells; one nameless group if none
    prediction: Mapping[str, Mapping[str, Any]]  # [prediction.<name>] (the paper: correctness)
    confidence: Mapping[str, Any]
    policy: Mapping[str, Any]
    training: Training
    scenes: Mapping[str, SceneSpec]
    questionnaire: Questionnaire
    texts: Texts
    content_hash: str
    software_version: str
    source: str = ""

    # -- lookups ---------------------------------------------------------------------------
    @property
    def id(self) -> str:
        return self.study.id

    @property
    def task_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.tasks)

    @property
    def mode_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.modes)

    @property
    def factors(self) -> dict[str, tuple[str, ...]]:
        """Factor -> levels, in file order (the paper: ``difficulty``, ``correctness``,
        ``mode``). Every level listed here is blinded (:attr:`condition_words`)."""
        return {f.name: f.levels for f in self.declared}

    @property
    def within_factors(self) -> tuple[str, ...]:
        """Names of the factors every participant meets every level of, in file order."""
        return tuple(f.name for f in self.declared if not f.between)

    @property
    def between_factors(self) -> tuple[str, ...]:
        """Names of the factors each participant meets one level of, in file order."""
        return tuple(f.name for f in self.declared if f.between)

    @property
    def group_names(self) -> tuple[str, ...]:
        return tuple(g.name for g in self.groups)

    def group_for(self, row: int) -> Group:
        """The between-subjects group of design row ``row`` (``study.schedule``: rows cycle
        through the groups, so every whole cycle fills each group equally)."""
        return self.groups[row % len(self.groups)]

    def levels(self, task: str | None, mode: str | None, *, row: int) -> dict[str, str]:
        """Every declared factor's level in one trial of design row ``row`` (a training run,
        ``task`` None: the between factors' only), in file order."""
        found: dict[str, str] = dict(self.group_for(row).levels)
        if task is not None:
            found.update(self.task(task).levels)
        if mode is not None and mode != TRAINING_MODE:
            found.update(self.mode(mode).levels)
        return {f.name: found[f.name] for f in self.declared if f.name in found}

    @functools.cached_property
    def condition_words(self) -> tuple[str, ...]:
        """Every word that would reveal a condition to the participant, lower-cased: the fixed
        list :data:`study.protocol.blinding.FIXED_WORDS`, every level of every factor in
        :attr:`factors`, every task and mode name. The loader checks participant-facing text
        against it; the study server guards the wire with it."""
        return blinded_words(self.factors, tasks=self.task_names, modes=self.mode_names)

    def task(self, name: str) -> Task:
        for t in self.tasks:
            if t.name == name:
                return t
        raise ConditionError(f"protocol {self.id!r} has no task {name!r}; tasks: {self.task_names}")

    def mode(self, name: str) -> Mode:
        for m in self.modes:
            if m.name == name:
                return m
        raise ConditionError(f"protocol {self.id!r} has no mode {name!r}; modes: {self.mode_names}")

    def scene_for(self, task: str) -> SceneSpec:
        return self.scenes[self.task(task).scene]

    def goal_names(self, task: str) -> tuple[str, ...]:
        """The objects of the task's scene in goal order (index k of the probability vector)."""
        return self.scene_for(task).object_names

    @property
    def consent_text(self) -> str:
        return self.texts.consent

    @property
    def debrief_text(self) -> str:
        return self.texts.debrief

    def instructions(self, phase: str) -> str:
        """Participant-facing instructions for ``phase`` (``{target}`` left unfilled)."""
        try:
            return self.texts.instructions[phase]
        except KeyError:
            raise ConditionError(
                f"protocol {self.id!r} has no instructions for {phase!r};"
                f" phases: {tuple(self.texts.instructions)}"
            ) from None

    # -- participant-facing descriptions ------------------------------------------------------
    def describe_trial(self, task: str) -> str:
        """What the participant is told before a task trial, e.g. "Pick up the bottle ...".

        Depends only on the scene's target, never on the condition (checked on load).
        """
        return _fill(self.texts.instructions["task"], self.scene_for(task).target)

    def describe_training(self) -> str:
        """What the participant is told before each training run."""
        return _fill(self.texts.instructions["training"], self.scenes[self.training.scene].target)

    # -- trial configurations -----------------------------------------------------------------
    def trial_config(self, task: str, mode: str, *, row: int = 0) -> TrialConfig:
        """The :class:`app.trial.TrialConfig` of one condition: ``task`` done in ``mode`` by
        a participant of design row ``row`` (whose group's settings apply)."""
        t = self.task(task)
        m = self.mode(mode)
        group = self.group_for(row).settings
        return TrialConfig(
            scene=self.scenes[t.scene],
            prediction=t.prediction,
            confidence=_first(m.confidence, group.get("confidence"), self.confidence),
            arbitration=m.arbitration,
            policy=_first(m.policy, group.get("policy"), self.policy),
            rate_hz=self.control.rate_hz,
            physics_dt=self.control.physics_dt,
            time_limit_s=t.time_limit_s,
            lift_height_m=self.control.lift_height_m,
            on_knock=self.control.on_knock,
            task=t.name,
            mode=m.name,
            extra=self._extra(
                difficulty=t.difficulty or "",
                correctness=t.correctness or "",
                phase="task",
                intent=m.intent if m.intent != "none" else group.get("intent", "none"),
                input_mapping=_first(
                    m.input_mapping, group.get("input_mapping"), self.control.input_mapping
                ),
                **_latency(m.latency_s, group.get("latency_s")),
            ),
        )

    def config_for(
        self, task: str, mode: str, *, time_limit_s: float | None = None, row: int = 0
    ) -> TrialConfig:
        """Like :meth:`trial_config`, plus ``mode="none"`` (unassisted, alpha = 0),
        ``task="training"`` (the training run) and an optional time-limit override."""
        if task == "training":
            config = self.training_config(row=row)
        elif mode == "none":
            config = dataclasses.replace(
                self.trial_config(task, self.mode_names[0], row=row), arbitration=None, mode="none"
            )
        else:
            config = self.trial_config(task, mode, row=row)
        if time_limit_s is not None:
            config = dataclasses.replace(config, time_limit_s=time_limit_s)
        return config

    def training_config(self, *, row: int = 0) -> TrialConfig:
        """The unassisted training run (arbitration ``None``, mode ``"none"``) of a participant
        of design row ``row`` (trained with their group's input mapping)."""
        group = self.group_for(row).settings
        return TrialConfig(
            scene=self.scenes[self.training.scene],
            prediction=self.training.prediction,
            confidence=self.confidence,
            arbitration=None,
            policy=self.policy,
            rate_hz=self.control.rate_hz,
            physics_dt=self.control.physics_dt,
            time_limit_s=self.training.time_limit_s,
            lift_height_m=self.control.lift_height_m,
            on_knock=self.control.on_knock,
            task="training",
            mode=TRAINING_MODE,
            extra=self._extra(
                difficulty="",
                correctness="",
                phase="training",
                intent="none",
                input_mapping=group.get("input_mapping", self.control.input_mapping),
                **_latency(group.get("latency_s")),
            ),
        )

    def _extra(self, *, input_mapping: str, **fields: Any) -> dict[str, Any]:
        """Labels a trial carries beside its settings; ``input_mapping`` (``[control]``'s
        unless a level sets it) is read from here by the page and simulated participants."""
        return {
            "protocol": self.id,
            "protocol_version": self.study.version,
            "content_hash": self.content_hash,
            "input_mapping": input_mapping,
            **fields,
        }


def _first(*values: Any) -> Any:
    """The first of ``values`` that is not None (a mode's setting, its group's, the default)."""
    return next(v for v in values if v is not None)


def _latency(*values: float | None) -> dict[str, float]:
    """``{"latency_s": s}`` when a level sets added latency (the first set of ``values``), else
    nothing: the trial's input is then not delayed (``app.teleop.delayed_input``)."""
    value = next((v for v in values if v is not None), None)
    return {} if value is None else {"latency_s": float(value)}


def _fill(template: str, target: str) -> str:
    return template.format(target=target.replace("_", " "))

"""``TrialConfig``: everything one trial needs, validated once, immutable.

The protocol layer builds these from TOML (``SceneSpec.from_dict`` for the scene, plain dicts for
prediction / confidence / arbitration / policy, which the trial turns into ``app.blending``
objects with the ``*_from_config`` factories). Already-built blending objects are accepted too.
``arbitration=None`` means unassisted (alpha = 0): training runs and the ``none`` mode.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from app.robot.scene_spec import SceneSpec
from app.trial.errors import TrialConfigError

ConfigOrObject = Mapping[str, Any] | Any

ON_KNOCK = ("reset", "end")
"""What an object knocked over or pushed off the table does to the run (``on_knock``)."""


def _freeze(value: Any) -> Any:
    if isinstance(value, Mapping):
        return MappingProxyType({k: _freeze(v) for k, v in value.items()})
    if isinstance(value, list):
        return tuple(_freeze(v) for v in value)
    return value


@dataclass(frozen=True, eq=False)
class TrialConfig:
    """One trial's settings.

    ``on_knock``: ``"reset"`` (an object knocked over or pushed off the table is put back at
    its start pose once it settles and the run goes on, as an experimenter would) or ``"end"``
    (the first such accident ends the trial); see ``app.trial.accidents``.

    ``physics_dt`` must divide the control period ``1 / rate_hz``: each control tick runs
    ``substeps = round(1 / (rate_hz * physics_dt))`` MuJoCo steps.
    """

    scene: SceneSpec
    prediction: ConfigOrObject
    confidence: ConfigOrObject
    arbitration: ConfigOrObject | None
    policy: ConfigOrObject
    rate_hz: float = 100.0
    physics_dt: float = 0.002
    time_limit_s: float = 120.0
    lift_height_m: float = 0.05
    on_knock: str = "reset"
    task: str = ""
    mode: str = ""
    extra: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.scene, SceneSpec):
            raise TrialConfigError(
                f"TrialConfig.scene: expected a SceneSpec (use SceneSpec.from_dict), got"
                f" {type(self.scene).__name__}"
            )
        for name in ("prediction", "confidence", "policy"):
            if getattr(self, name) is None:
                raise TrialConfigError(f"TrialConfig.{name}: required (a config table or object)")
        for name in ("prediction", "confidence", "arbitration", "policy", "extra"):
            object.__setattr__(self, name, _freeze(getattr(self, name)))
        _check_number("rate_hz", self.rate_hz, 10.0, 1000.0)
        _check_number("physics_dt", self.physics_dt, 1e-4, 0.01)
        _check_number("time_limit_s", self.time_limit_s, 0.1, 3600.0)
        _check_number("lift_height_m", self.lift_height_m, 0.005, 0.3)
        if self.on_knock not in ON_KNOCK:
            raise TrialConfigError(
                f"TrialConfig.on_knock: one of {', '.join(ON_KNOCK)}, got {self.on_knock!r}"
            )
        ratio = 1.0 / (self.rate_hz * self.physics_dt)
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise TrialConfigError(
                f"TrialConfig: physics_dt={self.physics_dt} s must divide the control period"
                f" 1/rate_hz={1.0 / self.rate_hz} s a whole number of times"
            )

    @property
    def substeps(self) -> int:
        """Physics steps per control tick."""
        return round(1.0 / (self.rate_hz * self.physics_dt))

    @property
    def dt(self) -> float:
        """Control period, seconds."""
        return 1.0 / self.rate_hz

    @property
    def assisted(self) -> bool:
        return self.arbitration is not None


def _check_number(name: str, value: Any, lo: float, hi: float) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise TrialConfigError(f"TrialConfig.{name}: expected a finite number, got {value!r}")
    if not lo <= value <= hi:
        raise TrialConfigError(f"TrialConfig.{name}: {value} outside [{lo}, {hi}]")

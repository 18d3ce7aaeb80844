"""Builders from plain dicts (protocol tables), reading the kinds' specifications.

Each ``*_from_config`` checks a table against its kind's declaration in the registry
(:mod:`app.blending.spec`; the built-in kinds are in :mod:`app.blending.kinds`) and builds the
component. Examples (TOML tables as dicts)::

    {"kind": "timid", "alpha_max": 0.5, "saturation": 0.7}        arbitration
    {"kind": "aggressive", "threshold": 0.4, "alpha_high": 0.9}   arbitration
    {"kind": "memory", "space": "workspace", "cost": "length", "rationality": 20.0}
    {"kind": "oracle"}          (goal from the ``target`` argument or a ``goal`` key)
    {"kind": "distance", "D": 0.4}
    {"kind": "straight_line", "max_speed": 1.0}      (configuration units per second)

``app.blending.spec.markdown()`` lists every kind and parameter. An error reads
``"<where>.<key>: <problem>"``, e.g.
``"modes.timid.arbitration.alpha_max: must be in (0, 1), got 1.5"``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from . import kinds as _kinds  # noqa: F401  (registers the built-in kinds)
from .arbitration import Arbitration
from .confidence import Confidence
from .errors import ConfigError
from .policy import Policy
from .prediction import Predictor
from .spec import BuildContext, build

__all__ = [
    "arbitration_from_config",
    "confidence_from_config",
    "policy_from_config",
    "predictor_from_config",
]


def arbitration_from_config(
    cfg: Any, *, where: str = "arbitration", rate_hz: float | None = None
) -> Arbitration:
    """Arbitration from a table (``rate_hz``: the control rate, for kinds with time
    constants)."""
    return build("arbitration", cfg, BuildContext(where, rate_hz=rate_hz))


def confidence_from_config(cfg: Any, *, where: str = "confidence") -> Confidence:
    """Confidence measure from a table."""
    return build("confidence", cfg, BuildContext(where))


def predictor_from_config(
    cfg: Any,
    *,
    points: Any,
    where: str = "prediction",
    target: int | str | None = None,
    rate_hz: float | None = None,
) -> Predictor:
    """Goal predictor from a table.

    ``points``: a :class:`GoalSet` (the table's ``space`` key, ``"workspace"`` by default,
    picks positions or configurations) or an ``(n, d)`` array used as is.
    ``target``: the goal index or name for ``oracle`` (the study's Right conditions); a
    ``goal`` key in the table (index or name) is used when ``target`` is None.
    """
    return build(
        "prediction", cfg, BuildContext(where, points=points, target=target, rate_hz=rate_hz)
    )


def policy_from_config(
    cfg: Any,
    *,
    rate_hz: float,
    where: str = "policy",
    fk: Callable[[np.ndarray], Any] | None = None,
    jacobian: Callable[[np.ndarray], Any] | None = None,
    arm: Any = None,
) -> Policy:
    """Policy from a table, with ``max_speed`` per second turned into ``max_step = max_speed /
    rate_hz`` per tick. ``fk``/``jacobian``: the workspace line's kinematics; ``arm``: the
    grasping policy's :class:`~app.blending.policy_grasp.ArmModel`."""
    if (
        isinstance(rate_hz, bool)
        or not isinstance(rate_hz, int | float)
        or not math.isfinite(rate_hz)
        or not rate_hz > 0
    ):
        raise ConfigError(f"{where}: rate_hz must be a finite number > 0, got {rate_hz!r}")
    return build(
        "policy",
        cfg,
        BuildContext(where, rate_hz=float(rate_hz), fk=fk, jacobian=jacobian, arm=arm),
    )

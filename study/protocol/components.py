"""Check the blending tables of a protocol: prediction, confidence, arbitration, policy.

Each table names a ``kind`` and that kind's parameters. The kinds, their parameters, types,
ranges and defaults are declared once, in ``app.blending`` (:mod:`app.blending.kinds`, listed in
``protocols/README.md``); this module only turns the registry's errors into protocol errors:

- :func:`component` checks one table's keys and types (an unknown key, a missing required one,
  a wrong type or an out-of-range value is a typed :class:`ProtocolError` naming the key and,
  for unknown keys, listing the allowed ones);
- :func:`build_check` then builds the table once with the ``app.blending`` builder, in the
  scene it will run in, so any constraint the formalism itself enforces (a prior's length
  matching the goals, an arbitration that must not decrease) fails on load, not in the
  middle of a session.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from app.blending import spec
from app.blending.config import (
    arbitration_from_config,
    confidence_from_config,
    policy_from_config,
    predictor_from_config,
)
from app.blending.errors import BlendingError, ConfigError
from app.blending.policy_grasp import ArmModel, HandLayer
from study.protocol.errors import (
    MissingKeyError,
    ProtocolError,
    ProtocolTypeError,
    ProtocolValueError,
    UnknownKeyError,
)
from study.protocol.fields import Table

_CHECK_ARM = ArmModel(
    pose_jacobian=lambda q: (np.zeros(3), np.eye(3), np.zeros((6, len(q)))),
    layers=(HandLayer(lo=0.0, hi=0.1, center=(0.0, 0.0), half=(0.05, 0.05)),),
    slot=0.04,
)

_ERRORS: dict[str, type[ProtocolError]] = {
    "missing": MissingKeyError,
    "unknown": UnknownKeyError,
    "type": ProtocolTypeError,
    "value": ProtocolValueError,
}


def _protocol_error(error: ConfigError, *, file: str, where: str) -> ProtocolError:
    key, problem = error.key, error.problem
    if not key.startswith(where):
        key, problem = where, str(error)
    return _ERRORS.get(error.category, ProtocolValueError)(problem, file=file, key=key)


def component(t: Table, role: str) -> dict[str, Any]:
    """Check one blending table of ``role`` against its kind's specification."""
    try:
        return spec.check(role, t.data, where=t.key, protocol=True)
    except ConfigError as e:
        raise _protocol_error(e, file=str(t.file), where=t.key) from None


def build_check(
    role: str,
    cfg: Mapping[str, Any],
    *,
    where: str,
    file: str,
    goals: int = 2,
    target: int = 0,
    rate_hz: float = 100.0,
) -> None:
    """Build ``cfg`` once with the ``app.blending`` builder for ``role``; its ``ConfigError``
    becomes a :class:`ProtocolError` at the key it names. ``goals``/``target`` describe
    the scene a predictor will run in."""
    try:
        if role == "prediction":
            points = np.linspace([0.3, -0.3, 0.05], [0.7, 0.3, 0.05], goals)
            predictor_from_config(
                dict(cfg), points=points, where=where, target=target, rate_hz=rate_hz
            )
        elif role == "confidence":
            confidence_from_config(dict(cfg), where=where)
        elif role == "arbitration":
            arbitration_from_config(dict(cfg), where=where, rate_hz=rate_hz)
        else:  # the arm's kinematics and hand come with the scene: stand-ins to check the table
            policy_from_config(
                dict(cfg),
                rate_hz=rate_hz,
                where=where,
                fk=lambda q: q[:3],
                jacobian=lambda q: np.zeros((6, len(q))),
                arm=_CHECK_ARM,
            )
    except ConfigError as e:
        raise _protocol_error(e, file=file, where=where) from None
    except BlendingError as e:
        raise ProtocolValueError(str(e), file=file, key=where) from None

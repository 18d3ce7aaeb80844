"""Check the blending tables of a protocol: prediction, confidence, arbitration, policy.

Each table names a ``kind`` and that kind's parameters (formulas and defaults live in
``app.blending``; its ``*_from_config`` factories read the same tables):

    prediction    oracle                              told the scene's target ("right")
                  amnesic   space, temperature        softmin of ||x - g|| ("wrong")
                  memory    space, cost, rationality, prior, steps    eq. 9, incremental
                  laplace   space, cost, rationality, prior, steps    eq. 8
    confidence    distance  D                         c = max(0, 1 - d / D)
                  probability | entropy | margin
    arbitration   timid     alpha_max, saturation     plateaus at alpha_max
                  aggressive threshold, alpha_high    jumps to alpha_high at the threshold
                  linear    alpha_min, alpha_max
                  piecewise_linear points = [[c, alpha], ...], non-decreasing
                  none                                alpha = 0 (unassisted)
    policy        straight_line  max_speed            configuration units per second
                  workspace_line max_speed, damping   metres per second

:func:`component` checks keys and types here (typed errors naming the key); the protocol loader
then builds each table once with the ``app.blending`` factory (:func:`build_check`), so any
constraint the formalism itself enforces (e.g. a prior's length matching the goals) fails on
load, not in the middle of a session.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from study.protocol.errors import ProtocolValueError
from study.protocol.fields import Table, check_number

SPACES = ("workspace", "configuration")
COSTS = ("length", "squared_velocity")

_PARAMETERS: dict[str, tuple[str, ...]] = {
    "oracle": ("space",),  # the goal is the scene's target
    "amnesic": ("space", "temperature"),
    "memory": ("space", "cost", "rationality", "prior", "steps"),
    "laplace": ("space", "cost", "rationality", "prior", "steps"),
    "distance": ("D",),
    "probability": (),
    "entropy": (),
    "margin": (),
    "timid": ("alpha_max", "saturation"),
    "aggressive": ("threshold", "alpha_high"),
    "linear": ("alpha_min", "alpha_max"),
    "piecewise_linear": ("points",),
    "none": (),
    "straight_line": ("max_speed",),
    "workspace_line": ("max_speed", "damping"),
}


def _predictor_params(t: Table, kind: str, out: dict[str, Any]) -> None:
    if "space" in t:
        out["space"] = t.choice("space", SPACES)
    if kind == "oracle":
        return
    if kind == "amnesic":
        if "temperature" in t:
            out["temperature"] = t.number("temperature", positive=True)
        return
    if "cost" in t:
        out["cost"] = t.choice("cost", COSTS)
    if "rationality" in t:
        out["rationality"] = t.number("rationality", positive=True)
    if "steps" in t:
        out["steps"] = t.integer("steps", minimum=1, maximum=1000)
    if "prior" in t:
        prior = t.array("prior")
        values = [check_number(t, f"prior[{i}]", v, minimum=0.0) for i, v in enumerate(prior)]
        if sum(values) <= 0:
            raise t.value_error("prior", "needs a positive entry")
        out["prior"] = values


def _confidence_params(t: Table, kind: str, out: dict[str, Any]) -> None:
    if kind == "distance":
        out["D"] = t.number("D", positive=True, maximum=5.0)


def _arbitration_params(t: Table, kind: str, out: dict[str, Any]) -> None:
    if kind == "piecewise_linear":
        points = t.array("points")
        pairs: list[list[float]] = []
        for i, p in enumerate(points):
            if not isinstance(p, list) or len(p) != 2:
                raise t.value_error(f"points[{i}]", f"expected [confidence, alpha], got {p!r}")
            c = check_number(t, f"points[{i}][0]", p[0], minimum=0.0, maximum=1.0)
            a = check_number(t, f"points[{i}][1]", p[1], minimum=0.0, maximum=1.0)
            if pairs and (c <= pairs[-1][0] or a < pairs[-1][1]):
                raise t.value_error(
                    f"points[{i}]",
                    "confidence must increase and alpha must not decrease (arbitration is"
                    " monotone in confidence)",
                )
            pairs.append([c, a])
        out["points"] = pairs
        return
    required = {"timid": ("alpha_max",), "aggressive": ("threshold",)}.get(kind, ())
    for key in _PARAMETERS[kind]:
        if key in t or key in required:
            out[key] = t.number(key, minimum=0.0, maximum=1.0)


def _policy_params(t: Table, kind: str, out: dict[str, Any]) -> None:
    out["max_speed"] = t.number("max_speed", positive=True, maximum=10.0)
    if "damping" in t:
        out["damping"] = t.number("damping", positive=True)


_KINDS: dict[str, tuple[tuple[str, ...], Callable[[Table, str, dict[str, Any]], None]]] = {
    "prediction": (("oracle", "amnesic", "memory", "laplace"), _predictor_params),
    "confidence": (("distance", "probability", "entropy", "margin"), _confidence_params),
    "arbitration": (
        ("timid", "aggressive", "linear", "piecewise_linear", "none"),
        _arbitration_params,
    ),
    "policy": (("straight_line", "workspace_line"), _policy_params),
}


def component(t: Table, role: str) -> dict[str, Any]:
    """Check one blending table of ``role`` (see the module docstring); unknown keys are errors."""
    kinds, parse = _KINDS[role]
    kind = t.choice("kind", kinds)
    t.only("kind", *_PARAMETERS[kind])
    out: dict[str, Any] = {"kind": kind}
    parse(t, kind, out)
    t.close(allowed=", ".join(("kind", *_PARAMETERS[kind])))
    return out


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
    """Build ``cfg`` once with the ``app.blending`` factory for ``role``; its ``ConfigError``
    becomes a :class:`ProtocolValueError` at the key it names. ``goals``/``target`` describe
    the scene a predictor will run in."""
    from app.blending.config import (
        arbitration_from_config,
        confidence_from_config,
        policy_from_config,
        predictor_from_config,
    )
    from app.blending.errors import BlendingError

    try:
        if role == "prediction":
            points = np.linspace([0.3, -0.3, 0.05], [0.7, 0.3, 0.05], goals)
            predictor_from_config(dict(cfg), points=points, where=where, target=target)
        elif role == "confidence":
            confidence_from_config(dict(cfg), where=where)
        elif role == "arbitration":
            arbitration_from_config(dict(cfg), where=where)
        else:
            policy_from_config(
                dict(cfg),
                rate_hz=rate_hz,
                where=where,
                fk=lambda q: q[:3],
                jacobian=lambda q: np.zeros((6, len(q))),
            )
    except BlendingError as e:
        message = str(e)
        key, sep, problem = message.partition(": ")
        if not sep or not key.startswith(where):
            key, problem = where, message
        raise ProtocolValueError(problem, file=file, key=key) from None

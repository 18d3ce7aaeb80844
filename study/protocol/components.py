"""Check the blending tables of a protocol: prediction, confidence, arbitration, policy.

Each table names a ``kind`` and that kind's parameters (the formulas are in ``app.blending``):

    prediction    oracle                      the robot is told the intended goal ("right")
                  amnesic   space, temperature   softmin of ||x - g|| ("wrong": the closer goal)
                  memory    space, cost, rationality, prior   eq. 9, incremental
                  laplace   space, cost, rationality, prior   eq. 8
    confidence    distance  D                 c = max(0, 1 - d / D)
                  probability | entropy | margin
    arbitration   timid     alpha_max, saturation      alpha = alpha_max * min(1, c / saturation)
                  aggressive threshold, alpha_high     alpha = alpha_high if c >= threshold else 0
                  linear    alpha_max                  alpha = alpha_max * c
                  piecewise_linear points = [[c, alpha], ...]  non-decreasing
                  none                                 alpha = 0 (unassisted)
    policy        straight_line | workspace_line  max_speed (rad/s per joint)

The checked table is returned as a plain dict (the form ``app.trial.TrialConfig`` takes).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from study.protocol.fields import Table, check_number

SPACES = ("workspace", "configuration")
COSTS = ("path_length", "squared_velocity")


def _predictor_params(t: Table, kind: str) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": kind}
    if kind == "oracle":
        return out
    out["space"] = t.choice("space", SPACES, "workspace")
    if kind == "amnesic":
        out["temperature"] = t.number("temperature", 0.05, positive=True)
        return out
    out["cost"] = t.choice("cost", COSTS, "squared_velocity")
    out["rationality"] = t.number("rationality", 1.0, positive=True)
    if "prior" in t:
        prior = t.array("prior")
        values = [check_number(t, f"prior[{i}]", v, minimum=0.0) for i, v in enumerate(prior)]
        if sum(values) <= 0:
            raise t.value_error("prior", "must have a positive entry")
        out["prior"] = values
    return out


def _confidence_params(t: Table, kind: str) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": kind}
    if kind == "distance":
        out["D"] = t.number("D", positive=True, maximum=5.0)
    return out


def _arbitration_params(t: Table, kind: str) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": kind}
    if kind == "timid":
        out["alpha_max"] = t.number("alpha_max", minimum=0.0, maximum=1.0)
        out["saturation"] = t.number("saturation", positive=True, maximum=1.0)
    elif kind == "aggressive":
        out["threshold"] = t.number("threshold", minimum=0.0, maximum=1.0)
        out["alpha_high"] = t.number("alpha_high", minimum=0.0, maximum=1.0)
    elif kind == "linear":
        out["alpha_max"] = t.number("alpha_max", minimum=0.0, maximum=1.0)
    elif kind == "piecewise_linear":
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
    return out


def _policy_params(t: Table, kind: str) -> dict[str, Any]:
    return {"kind": kind, "max_speed": t.number("max_speed", positive=True, maximum=10.0)}


_KINDS: dict[str, tuple[tuple[str, ...], Callable[[Table, str], dict[str, Any]]]] = {
    "prediction": (("oracle", "amnesic", "memory", "laplace"), _predictor_params),
    "confidence": (("distance", "probability", "entropy", "margin"), _confidence_params),
    "arbitration": (
        ("timid", "aggressive", "linear", "piecewise_linear", "none"),
        _arbitration_params,
    ),
    "policy": (("straight_line", "workspace_line"), _policy_params),
}


_PARAMETERS: dict[str, tuple[str, ...]] = {
    "oracle": (),
    "amnesic": ("space", "temperature"),
    "memory": ("space", "cost", "rationality", "prior"),
    "laplace": ("space", "cost", "rationality", "prior"),
    "distance": ("D",),
    "probability": (),
    "entropy": (),
    "margin": (),
    "timid": ("alpha_max", "saturation"),
    "aggressive": ("threshold", "alpha_high"),
    "linear": ("alpha_max",),
    "piecewise_linear": ("points",),
    "none": (),
    "straight_line": ("max_speed",),
    "workspace_line": ("max_speed",),
}


def component(t: Table, role: str) -> dict[str, Any]:
    """Check one blending table of ``role`` (see the module docstring); unknown keys are errors."""
    kinds, parse = _KINDS[role]
    kind = t.choice("kind", kinds)
    t.only("kind", *_PARAMETERS[kind])
    out = parse(t, kind)
    t.close(allowed=", ".join(out))
    return out

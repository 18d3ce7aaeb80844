"""Factories from plain dicts (protocol tables), with errors that name the key path.

Examples (TOML tables as dicts)::

    {"kind": "timid", "alpha_max": 0.5, "saturation": 0.7}        arbitration
    {"kind": "aggressive", "threshold": 0.4, "alpha_high": 0.9}   arbitration
    {"kind": "linear", "alpha_min": 0, "alpha_max": 1}            arbitration
    {"kind": "piecewise_linear", "points": [[0, 0], [0.5, 0.2], [1, 0.8]]}
    {"kind": "none"}                                              arbitration (alpha = 0)
    {"kind": "amnesic", "space": "workspace", "temperature": 0.05}
    {"kind": "memory", "space": "workspace", "cost": "length", "rationality": 20.0}
    {"kind": "memory", "cost": "squared_velocity", "steps": 10, "prior": [1, 1]}
    {"kind": "laplace", "cost": "squared_velocity", "steps": 10}
    {"kind": "oracle"}          (goal from the ``target`` argument or a ``goal`` key)
    {"kind": "distance", "D": 0.4} / {"kind": "probability"} / "entropy" / "margin"
    {"kind": "straight_line", "max_speed": 1.0}      (configuration units per second)
    {"kind": "workspace_line", "max_speed": 0.2}     (metres per second; needs fk, jacobian)

An error reads ``"<where>.<key>: <problem>"``, e.g.
``"modes.timid.arbitration.alpha_max: must be in (0, 1), got 1.5"``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .arbitration import (
    Aggressive,
    Arbitration,
    Linear,
    NoAssistance,
    PiecewiseLinear,
    Timid,
)
from .confidence import (
    Confidence,
    DistanceHinge,
    EntropyConfidence,
    MarginConfidence,
    ProbabilityConfidence,
)
from .errors import BlendingError, ConfigError
from .goals import GoalSet
from .policy import Policy, StraightLinePolicy, WorkspaceLinePolicy
from .prediction import (
    AmnesicPredictor,
    LaplacePredictor,
    MemoryPredictor,
    OraclePredictor,
    PathLengthCost,
    Predictor,
    SquaredVelocityCost,
)

__all__ = [
    "arbitration_from_config",
    "confidence_from_config",
    "policy_from_config",
    "predictor_from_config",
]


def _table(cfg: Any, where: str, kinds: tuple[str, ...]) -> tuple[str, dict[str, Any]]:
    if not isinstance(cfg, Mapping):
        raise ConfigError(f"{where}: expected a table with a 'kind' key, got {cfg!r}")
    if "kind" not in cfg:
        raise ConfigError(f"{where}.kind: missing; one of {list(kinds)}")
    kind = cfg["kind"]
    if kind not in kinds:
        raise ConfigError(f"{where}.kind: must be one of {list(kinds)}, got {kind!r}")
    rest = {k: v for k, v in cfg.items() if k != "kind"}
    return kind, rest


def _check_keys(rest: Mapping[str, Any], allowed: tuple[str, ...], where: str, kind: str) -> None:
    for key in rest:
        if key not in allowed:
            raise ConfigError(
                f"{where}.{key}: unknown key for kind {kind!r}; allowed: {list(allowed)}"
            )


def _build(where: str, rest: Mapping[str, Any], fn: Callable[..., Any], **kwargs: Any) -> Any:
    """Call ``fn(**kwargs)``, turning an error about argument ``name`` into one at
    ``where.name`` (the message of every BlendingError starts with the argument's name)."""
    try:
        return fn(**kwargs)
    except ConfigError:
        raise
    except BlendingError as exc:
        msg = str(exc)
        key, sep, tail = msg.partition(": ")
        if sep and key in rest:
            raise ConfigError(f"{where}.{key}: {tail}") from None
        raise ConfigError(f"{where}: {msg}") from None


def _require(rest: Mapping[str, Any], key: str, where: str, kind: str) -> Any:
    if key not in rest:
        raise ConfigError(f"{where}.{key}: missing (required for kind {kind!r})")
    return rest[key]


def arbitration_from_config(cfg: Any, *, where: str = "arbitration") -> Arbitration:
    """Arbitration from a table; ``kind`` in timid, aggressive, linear, piecewise_linear, none."""
    kinds = ("timid", "aggressive", "linear", "piecewise_linear", "none")
    kind, rest = _table(cfg, where, kinds)
    if kind == "timid":
        _check_keys(rest, ("alpha_max", "saturation"), where, kind)
        return _build(
            where,
            rest,
            Timid,
            alpha_max=_require(rest, "alpha_max", where, kind),
            saturation=rest.get("saturation", 1.0),
        )
    if kind == "aggressive":
        _check_keys(rest, ("threshold", "alpha_high"), where, kind)
        return _build(
            where,
            rest,
            Aggressive,
            threshold=_require(rest, "threshold", where, kind),
            alpha_high=rest.get("alpha_high", 1.0),
        )
    if kind == "linear":
        _check_keys(rest, ("alpha_min", "alpha_max"), where, kind)
        return _build(
            where,
            rest,
            Linear,
            alpha_min=rest.get("alpha_min", 0.0),
            alpha_max=rest.get("alpha_max", 1.0),
        )
    if kind == "piecewise_linear":
        _check_keys(rest, ("points",), where, kind)
        return _build(where, rest, PiecewiseLinear, points=_require(rest, "points", where, kind))
    _check_keys(rest, (), where, kind)
    return NoAssistance()


def confidence_from_config(cfg: Any, *, where: str = "confidence") -> Confidence:
    """Confidence from a table; ``kind`` in distance (key D), probability, entropy, margin."""
    kind, rest = _table(cfg, where, ("distance", "probability", "entropy", "margin"))
    if kind == "distance":
        _check_keys(rest, ("D",), where, kind)
        return _build(where, rest, DistanceHinge, D=_require(rest, "D", where, kind))
    _check_keys(rest, (), where, kind)
    return {
        "probability": ProbabilityConfidence,
        "entropy": EntropyConfidence,
        "margin": MarginConfidence,
    }[kind]()


def _points_for(points: Any, space: str | None, where: str) -> Any:
    if isinstance(points, GoalSet):
        try:
            return points.points(space or "workspace")
        except BlendingError as exc:
            raise ConfigError(f"{where}.space: {str(exc).partition(': ')[2]}") from None
    return points


def predictor_from_config(
    cfg: Any,
    *,
    points: Any,
    where: str = "prediction",
    target: int | str | None = None,
) -> Predictor:
    """Goal predictor from a table; ``kind`` in amnesic, memory, laplace, oracle.

    ``points``: a :class:`GoalSet` (the table's ``space`` key, ``"workspace"`` by default,
    picks positions or configurations) or an ``(n, d)`` array used as is.
    ``target``: the goal index or name for ``oracle`` (the study's Right conditions); a
    ``goal`` key in the table (index or name) is used when ``target`` is None.
    """
    kind, rest = _table(cfg, where, ("amnesic", "memory", "laplace", "oracle"))
    space = rest.get("space")
    if space is not None and space not in ("workspace", "configuration"):
        raise ConfigError(f"{where}.space: must be 'workspace' or 'configuration', got {space!r}")
    if kind == "oracle":
        _check_keys(rest, ("goal", "space"), where, kind)
        goal = target if target is not None else rest.get("goal")
        n = len(points)
        if goal is None:
            raise ConfigError(
                f"{where}.goal: oracle prediction needs the goal (pass target= or set 'goal')"
            )
        key = f"{where}.goal" if target is None else f"{where}: target"
        try:
            if isinstance(goal, str):
                if not isinstance(points, GoalSet):
                    raise ConfigError(f"{key}: a goal name needs points to be a GoalSet")
                goal = points.index(goal)
            pred = OraclePredictor(n, goal=goal)
        except ConfigError:
            raise
        except BlendingError as exc:
            raise ConfigError(f"{key}: {str(exc).partition(': ')[2]}") from None
        pred.space = space
        return pred
    pts = _points_for(points, space, where)
    space = space or ("workspace" if isinstance(points, GoalSet) else None)
    if kind == "amnesic":
        _check_keys(rest, ("space", "temperature"), where, kind)
        return _build(
            where,
            rest,
            AmnesicPredictor,
            points=pts,
            temperature=rest.get("temperature", 0.05),
            space=space,
        )
    _check_keys(rest, ("space", "cost", "rationality", "prior", "steps"), where, kind)
    cost_name = rest.get("cost", "length" if kind == "memory" else "squared_velocity")
    if cost_name == "length":
        if "steps" in rest:
            raise ConfigError(f"{where}.steps: only for cost 'squared_velocity'")
        if kind == "laplace":
            raise ConfigError(
                f"{where}.cost: eq. 8 needs a cost with a Hessian: 'squared_velocity'"
            )
        cost: Any = PathLengthCost()
    elif cost_name == "squared_velocity":
        cost = _build(where, rest, SquaredVelocityCost, steps=rest.get("steps", 1))
    else:
        raise ConfigError(
            f"{where}.cost: must be 'length' or 'squared_velocity', got {cost_name!r}"
        )
    prior = rest.get("prior")
    cls = MemoryPredictor if kind == "memory" else LaplacePredictor
    return _build(
        where,
        rest,
        cls,
        points=pts,
        cost=cost,
        rationality=rest.get("rationality", 1.0),
        prior=prior,
        space=space,
    )


def policy_from_config(
    cfg: Any,
    *,
    rate_hz: float,
    where: str = "policy",
    fk: Callable[[np.ndarray], Any] | None = None,
    jacobian: Callable[[np.ndarray], Any] | None = None,
) -> Policy:
    """Policy from a table; ``kind`` straight_line or workspace_line, with ``max_speed`` per
    second turned into ``max_step = max_speed / rate_hz`` per tick."""
    kind, rest = _table(cfg, where, ("straight_line", "workspace_line"))
    if (
        isinstance(rate_hz, bool)
        or not isinstance(rate_hz, (int, float))
        or not rate_hz > 0
        or not np.isfinite(rate_hz)
    ):
        raise ConfigError(f"{where}: rate_hz must be a finite number > 0, got {rate_hz!r}")
    speed = _require(rest, "max_speed", where, kind)
    if (
        isinstance(speed, bool)
        or not isinstance(speed, (int, float))
        or not speed > 0
        or not np.isfinite(speed)
    ):
        raise ConfigError(f"{where}.max_speed: must be a finite number > 0, got {speed!r}")
    step = float(speed) / float(rate_hz)
    if kind == "straight_line":
        _check_keys(rest, ("max_speed",), where, kind)
        return StraightLinePolicy(step)
    _check_keys(rest, ("max_speed", "damping"), where, kind)
    if fk is None or jacobian is None:
        raise ConfigError(f"{where}.kind: 'workspace_line' needs fk= and jacobian= callables")
    return _build(
        where,
        rest,
        WorkspaceLinePolicy,
        fk=fk,
        jacobian=jacobian,
        max_step=step,
        damping=rest.get("damping", 1e-3),
    )

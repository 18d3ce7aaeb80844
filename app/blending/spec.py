"""One specification per blending component kind, declared once and used everywhere.

A :class:`Kind` names a component kind of one *role* (``prediction``, ``confidence``,
``arbitration``, ``policy``), declares its parameters (:class:`Param`: name, type and range
from :mod:`app.blending.params`, default, one-line doc) and its factory. The registry built from these declarations is what the
``*_from_config`` builders, the protocol loader (``study.protocol.components``), the error
messages and the protocol documentation (:func:`markdown`) all read, so a new kind is one
declaration and one :func:`register` call::

    register(Kind(
        role="arbitration", name="half", doc="alpha = c / 2",
        params=(), factory=lambda params, ctx: FunctionArbitration(lambda c: c / 2),
    ))

:func:`check` validates a table (unknown keys first, then the kind, then each parameter's type
and range); :func:`build` checks, fills defaults and calls the factory with a
:class:`BuildContext`; an error is a :class:`ConfigError` whose ``key`` is the full key path
(``modes.timid.arbitration.alpha_max``) and whose ``category`` says whether the key was
``missing``, ``unknown``, of the wrong ``type`` or out of range (``value``). Every built
arbitration, whatever its kind, must pass :func:`check_arbitration` (once per stock kind and
parameters: :func:`~app.blending.arbitration.check_once`; alpha in [0, 1], never
decreasing in confidence; stateful kinds with their state frozen).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .arbitration import check_once
from .errors import BlendingError, ConfigError
from .params import ParamProblem, ParamType, type_name

__all__ = [
    "REQUIRED",
    "ROLES",
    "BuildContext",
    "Kind",
    "Param",
    "build",
    "check",
    "get",
    "kinds",
    "markdown",
    "register",
    "unregister",
]

ROLES = ("prediction", "confidence", "arbitration", "policy")
REQUIRED: Any = object()
"""The default of a parameter that has none."""


@dataclass(frozen=True)
class Param:
    """One parameter of a kind: ``name``, its type (with range), ``doc`` and ``default``
    (``REQUIRED`` when it has none). ``protocol=False`` keeps a parameter out of protocol files
    (e.g. the oracle's goal, which a trial takes from its scene)."""

    name: str
    type: ParamType
    doc: str
    default: Any = REQUIRED
    protocol: bool = True

    @property
    def required(self) -> bool:
        return self.default is REQUIRED


@dataclass(frozen=True)
class BuildContext:
    """What a factory may need besides its parameters: ``where`` (the table's key path, for
    errors), the goal ``points`` (a ``GoalSet`` or an ``(n, d)`` array) and the oracle's
    ``target`` (prediction), the control rate ``rate_hz`` (policies, stateful arbitrations),
    the arm's ``fk``/``jacobian`` callables (workspace policies) and ``arm``, an
    :class:`app.blending.policy_grasp.ArmModel` (policies that keep the hand clear of the
    scene)."""

    where: str
    points: Any = None
    target: int | str | None = None
    rate_hz: float | None = None
    fk: Callable[[Any], Any] | None = None
    jacobian: Callable[[Any], Any] | None = None
    arm: Any = None


Factory = Callable[[dict[str, Any], BuildContext], Any]


@dataclass(frozen=True)
class Kind:
    """A component kind: its ``role``, ``name``, one-line ``doc``, ``params`` and ``factory``
    (``factory(params, ctx)`` with every parameter present, defaults filled). ``example`` is a
    valid parameter set (docs and tests build it); ``needs`` names the :class:`BuildContext`
    fields the factory cannot do without."""

    role: str
    name: str
    doc: str
    params: tuple[Param, ...]
    factory: Factory
    example: Mapping[str, Any] = field(default_factory=dict)
    needs: tuple[str, ...] = ()

    def keys(self, *, protocol: bool = False) -> tuple[str, ...]:
        return tuple(p.name for p in self.params if p.protocol or not protocol)


_REGISTRY: dict[str, dict[str, Kind]] = {role: {} for role in ROLES}


def register(kind: Kind, *, replace: bool = False) -> Kind:
    """Add ``kind`` to the registry (``replace=True`` to redefine an existing name)."""
    if kind.role not in ROLES:
        raise ConfigError(f"role: must be one of {list(ROLES)}, got {kind.role!r}")
    if not kind.name or not kind.name.replace("_", "").isalnum():
        raise ConfigError(f"name: use letters, digits and '_', got {kind.name!r}")
    if kind.name in _REGISTRY[kind.role] and not replace:
        raise ConfigError(f"name: {kind.role} kind {kind.name!r} exists; pass replace=True")
    names = [p.name for p in kind.params]
    if len(set(names)) != len(names) or "kind" in names:
        raise ConfigError(f"params: names must be unique and not 'kind', got {names}")
    _REGISTRY[kind.role][kind.name] = kind
    return kind


def unregister(role: str, name: str) -> None:
    """Remove a kind (tests that register their own)."""
    kinds(role).pop(name, None)


def kinds(role: str) -> dict[str, Kind]:
    """The registered kinds of ``role``, by name (in registration order)."""
    if role not in _REGISTRY:
        raise ConfigError(f"role: must be one of {list(ROLES)}, got {role!r}")
    return _REGISTRY[role]


def get(role: str, name: str) -> Kind:
    known = kinds(role)
    if name not in known:
        raise ConfigError(
            f"kind: {name!r} is not one of {', '.join(known)}", key="kind", category="value"
        )
    return known[name]


def _error(where: str, key: str, category: str, problem: str) -> ConfigError:
    path = f"{where}.{key}" if where else key
    return ConfigError(f"{path}: {problem}", key=path, category=category, problem=problem)


def check(role: str, cfg: Any, *, where: str, protocol: bool = False) -> dict[str, Any]:
    """The table ``cfg`` checked against its kind's specification: ``{"kind": ..., **given}``
    with each given value normalised (numbers as float). Defaults are not filled in.
    ``protocol=True`` rejects parameters that protocol files may not set."""
    if not isinstance(cfg, Mapping):
        raise ConfigError(f"{where}: expected a table with a 'kind' key, got {cfg!r}", key=where)
    known = kinds(role)
    if "kind" not in cfg:
        raise _error(where, "kind", "missing", f"missing; one of {', '.join(known)}")
    name = cfg["kind"]
    if not isinstance(name, str):
        raise _error(where, "kind", "type", f"expected a string, got {type_name(name)}")
    if name not in known:
        raise _error(where, "kind", "value", f"{name!r} is not one of {', '.join(known)}")
    kind = known[name]
    allowed = kind.keys(protocol=protocol)
    for key in cfg:
        if key != "kind" and key not in allowed:
            raise _error(
                where,
                key,
                "unknown",
                f"unknown key {key!r} for kind {name!r} (allowed here: "
                f"{', '.join(('kind', *allowed))}); check the spelling",
            )
    out: dict[str, Any] = {"kind": name}
    for p in kind.params:
        if p.name not in cfg:
            if p.required:
                raise _error(where, p.name, "missing", f"missing (required for kind {name!r})")
            continue
        try:
            out[p.name] = p.type.check(cfg[p.name])
        except ParamProblem as e:
            raise _error(where, p.name, e.category, e.problem) from None
    return out


def build(role: str, cfg: Any, ctx: BuildContext) -> Any:
    """Check ``cfg``, fill defaults and build the component with its kind's factory.

    A :class:`BlendingError` from a constructor (whose message starts with the argument's name)
    becomes a :class:`ConfigError` at ``ctx.where.<name>`` when that names a parameter."""
    params = check(role, cfg, where=ctx.where)
    kind = get(role, params.pop("kind"))
    for p in kind.params:
        params.setdefault(p.name, None if p.required else p.default)
    for need in kind.needs:
        if getattr(ctx, need) is None:
            raise _error(ctx.where, "kind", "value", f"{kind.name!r} needs {need}= to be given")
    try:
        obj = kind.factory(params, ctx)
        if role == "arbitration":
            check_once(obj, name=kind.name, extra=getattr(obj, "_breakpoints", ()))
    except ConfigError:
        raise
    except BlendingError as exc:
        key, sep, tail = str(exc).partition(": ")
        if sep and key in params:
            raise _error(ctx.where, key, "value", tail) from None
        raise ConfigError(f"{ctx.where}: {exc}", key=ctx.where) from None
    return obj


def markdown() -> str:
    """The component table of ``protocols/README.md``, generated from the registry."""
    rows = [
        "| table | kind | parameters (type, default) |",
        "|---|---|---|",
    ]
    for role in ROLES:
        for kind in kinds(role).values():
            params = [
                f"`{p.name}` ({p.type.describe()}; {_default(p)}): {_cell(p.doc)}"
                for p in kind.params
                if p.protocol
            ]
            rows.append(
                f"| {role} | `{kind.name}`: {_cell(kind.doc)} | {'<br>'.join(params) or '-'} |"
            )
    return "\n".join(rows)


def _default(p: Param) -> str:
    if p.required:
        return "required"
    return "optional" if p.default is None else f"default {p.default!r}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")

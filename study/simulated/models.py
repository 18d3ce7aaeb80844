"""Simulated-user models: one declaration per model, named by the population file.

A :class:`UserModel` says which parameter tables a population file gives for it (``sections``:
table name -> a frozen dataclass whose fields are that table's parameters, each drawn from its
distribution), how one draw becomes the participant's parameters (``params``, called as
``params(index=i, seed=s, **sections)``; a dataclass, stored with the session as drawn), and the
participant it makes of them (``participant``): the input factory and answerer the headless
session loop drives (``study.session.headless.run_headless``)::

    register(UserModel(
        name="straight", doc="straight to the target at a drawn speed",
        sections={"straight": StraightParams},
        params=StraightPerson.Params, participant=StraightPerson,
    ))

A population file names its model in its ``[population]`` table (``model = "straight"``; the
default is ``"interface"``, :mod:`study.simulated.participant`'s model of a person on the page's
gizmo or keys). A new model is that one declaration and one :func:`register` call. Worker
processes and Dask workers import their own registry: a model registered only in the parent
(a script, a test) runs with ``workers=1`` on the local engine; for more, register it in a
module the workers import too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from study.simulated.errors import PopulationError

if TYPE_CHECKING:
    from app.teleop.types import InputSource
    from app.trial import TrialConfig
    from study.protocol import Answer
    from study.session.screen import Screen
    from study.session.trial_run import TrialSummary

__all__ = [
    "DEFAULT_MODEL",
    "SimulatedPerson",
    "UserModel",
    "get_model",
    "models",
    "register",
    "unregister",
]

DEFAULT_MODEL = "interface"
"""The model of a population file that names none."""


class SimulatedPerson(Protocol):
    """One simulated person across a session: an input source per trial attempt, and answers."""

    def __call__(self, config: TrialConfig, seed: int) -> InputSource:
        """A fresh input source for one trial attempt (``seed``: the attempt's)."""

    def observe(self, summary: TrialSummary | None, *, time_limit_s: float) -> None:
        """A run just finished (``None``: aborted, not lived to the end)."""

    def answer(self, screen: Screen) -> dict[str, Answer]:
        """Answers to every item on a questionnaire screen."""


@dataclass(frozen=True)
class UserModel:
    """A simulated-user model (module docstring)."""

    name: str
    doc: str
    sections: Mapping[str, type]
    params: Callable[..., Any]
    participant: Callable[[Any], SimulatedPerson]


_REGISTRY: dict[str, UserModel] = {}


def register(model: UserModel, *, replace: bool = False) -> UserModel:
    """Add ``model`` to the registry (``replace=True`` to redefine an existing name)."""
    if not model.name or not model.name.replace("_", "").isalnum():
        raise PopulationError(f"model name: use letters, digits and '_', got {model.name!r}")
    if model.name in _REGISTRY and not replace:
        raise PopulationError(f"model {model.name!r} exists; pass replace=True to redefine it")
    if not model.sections or "population" in model.sections:
        raise PopulationError(
            f"model {model.name!r}: give at least one parameter table, none named 'population'"
        )
    _REGISTRY[model.name] = model
    return model


def unregister(name: str) -> None:
    """Remove a model (tests that register their own)."""
    _REGISTRY.pop(name, None)


def models() -> dict[str, UserModel]:
    """The registered models, by name (in registration order)."""
    return _REGISTRY


def get_model(name: str, *, where: str = "model") -> UserModel:
    """The model called ``name``; ``where`` names the key for the error."""
    if name not in _REGISTRY:
        raise PopulationError(
            f"{where}: {name!r} is not a simulated-user model; known: {', '.join(_REGISTRY)}"
        )
    return _REGISTRY[name]

"""``app.frozen.quick_init``: the same instances as the dataclass's own ``__init__``, faster.

References: the same class decorated by ``dataclass`` alone. Checked: the signature (names,
order, defaults), equality, ``repr``, frozenness, ``__post_init__``, slots and ``__dict__``
classes, and the classes the control tick builds (observation, command, record).
"""

from __future__ import annotations

import dataclasses
import inspect
import math

import numpy as np
import pytest

from app.frozen import quick_init
from app.teleop.types import TeleopCommand, TrialObservation
from app.trial.records import TickRecord


def _pair(*, slots: bool) -> tuple[type, type]:
    """The same frozen dataclass twice: as ``dataclass`` writes it, and with ``quick_init``."""

    def make() -> type:
        @dataclasses.dataclass(frozen=True, slots=slots)
        class Point:
            x: float
            y: float = 2.0
            tag: str | None = None
            seen: tuple[int, ...] = ()

            def __post_init__(self) -> None:
                if self.tag is None:
                    object.__setattr__(self, "tag", f"{self.x},{self.y}")

        return Point

    return make(), quick_init(make())


@pytest.mark.parametrize("slots", [False, True])
def test_quick_init_builds_what_the_dataclass_builds(slots: bool) -> None:
    plain, quick = _pair(slots=slots)
    assert inspect.signature(quick.__init__) == inspect.signature(plain.__init__)
    for args, kw in (((1.0,), {}), ((1.0, 3.0), {"tag": "t"}), ((), {"x": 0.5, "seen": (1,)})):
        a, b = plain(*args, **kw), quick(*args, **kw)
        assert dataclasses.astuple(a) == dataclasses.astuple(b)
        assert repr(a).replace("plain", "") == repr(b)
        assert b.tag == a.tag  # __post_init__ ran
        with pytest.raises(dataclasses.FrozenInstanceError):
            b.x = 2.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        quick()  # x is required, as before
    with pytest.raises(TypeError):
        quick(1.0, 2.0, None, (), 5)  # one too many


def test_quick_init_refuses_what_it_cannot_build() -> None:
    @dataclasses.dataclass
    class Mutable:
        x: float

    @dataclasses.dataclass(frozen=True)
    class Factory:
        x: list[int] = dataclasses.field(default_factory=list)

    @dataclasses.dataclass(frozen=True)
    class KeywordOnly:
        x: float = dataclasses.field(kw_only=True, default=0.0)

    for cls in (Mutable, Factory, KeywordOnly, int):
        with pytest.raises(TypeError, match="quick_init"):
            quick_init(cls)


def test_the_ticks_records_are_built_as_before() -> None:
    """The observation, command and record keep their fields, defaults and frozenness."""
    q = np.arange(7.0)
    rec = TickRecord(1, 0.01, q, q, q, q, 0.5, 0.2, np.array([0.5, 0.5]), 0, q[:3], q[:3], 0.04)
    assert rec.events == () and rec.motion_agreement == 0.0 and math.isnan(rec.rationality)
    assert [f.name for f in dataclasses.fields(TickRecord)] == list(TickRecord.__slots__)
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.alpha = 1.0  # type: ignore[misc]
    cmd = TeleopCommand(q[:3])
    assert cmd.grasp is False and cmd.path is None
    obs = TrialObservation(0.0, q, q[:3], False, q[:3], None, ("a",), q[:3].reshape(1, 3), 0)  # type: ignore[arg-type]
    assert obs.grasp_points is obs.goal_positions  # its __post_init__'s default
    with pytest.raises(dataclasses.FrozenInstanceError):
        obs.t = 1.0  # type: ignore[misc]

"""The intent display: the ring's rules, and the protocol option that turns it on."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from study.protocol import load_protocol, parse_protocol
from study.protocol.errors import ProtocolValueError
from study.schedule import Design
from study.server.intent_cue import (
    OPACITY_MAX,
    RING_COLOR,
    RING_NODE,
    IntentCue,
    IntentGoals,
    ring_mesh,
    ring_opacity,
)

ROOT = Path(__file__).resolve().parents[1]
INTENT = ROOT / "protocols" / "intent.toml"


class FakeHandle:
    """Records every property the cue sets, in order (what viser would send)."""

    def __init__(self) -> None:
        object.__setattr__(self, "sets", [])
        object.__setattr__(self, "state", {})

    def __setattr__(self, name: str, value: Any) -> None:
        self.sets.append(name)
        self.state[name] = value

    def __getattr__(self, name: str) -> Any:
        return self.state[name]


class FakeScene:
    def __init__(self) -> None:
        self.added: list[tuple[str, dict[str, Any]]] = []
        self.handle = FakeHandle()

    def add_mesh_simple(self, name: str, vertices: Any, faces: Any, **kw: Any) -> FakeHandle:
        self.added.append((name, kw))
        self.handle.state.update(visible=kw["visible"], opacity=kw["opacity"])
        return self.handle


GOALS = IntentGoals(body_ids=(3, 5), radii=(0.035, 0.03), table_top=0.0)


def _xpos(box=(0.64, 0.06), bottle=(0.55, -0.08)) -> np.ndarray:
    xpos = np.zeros((8, 3))
    xpos[3, :2], xpos[5, :2] = box, bottle
    return xpos


def test_ring_opacity_is_hidden_below_the_threshold_and_grows_with_confidence() -> None:
    assert ring_opacity(0.0) == ring_opacity(0.14) == 0.0
    assert ring_opacity(float("nan")) == 0.0
    assert ring_opacity(0.2) == pytest.approx(0.2 * OPACITY_MAX)
    assert ring_opacity(1.0) == pytest.approx(OPACITY_MAX) == ring_opacity(1.7)
    values = [ring_opacity(c) for c in np.linspace(0, 1, 101)]
    assert values == sorted(values)
    assert len(set(values)) == 10  # 0 and nine steps of 0.1 from 0.2 to 1.0
    assert ring_opacity(0.52) == ring_opacity(0.48)  # quantised: small changes send nothing


def test_ring_mesh_is_a_flat_annulus() -> None:
    v, f = ring_mesh(inner=0.5, outer=1.0, segments=16)
    r = np.linalg.norm(v[:, :2], axis=1)
    assert v.shape == (32, 3) and f.shape == (32, 3) and np.all(v[:, 2] == 0)
    assert np.allclose(sorted(set(np.round(r, 6))), [0.5, 1.0])
    assert f.max() == 31
    with pytest.raises(ValueError):
        ring_mesh(inner=1.0, outer=0.5)


def test_ring_follows_the_prediction_and_the_object_and_sends_nothing_idle() -> None:
    scene = FakeScene()
    cue = IntentCue(scene, GOALS)
    ((name, kw),) = scene.added
    assert name == RING_NODE and kw["color"] == RING_COLOR and kw["visible"] is False
    h = scene.handle
    cue.update(_xpos(), 0, 0.1)  # not confident enough: nothing shown, nothing sent
    assert cue.visible_goal is None and h.sets == []
    cue.update(_xpos(), 0, 0.63)
    assert cue.visible_goal == 0 and h.visible is True
    assert h.position[:2] == pytest.approx((0.64, 0.06)) and h.opacity == pytest.approx(
        0.6 * OPACITY_MAX
    )
    inner = h.scale[0] * 0.72
    assert inner == pytest.approx(0.035 + 0.012)  # clears the box's footprint
    n, sets = cue.updates, len(h.sets)
    cue.update(_xpos(), 0, 0.61)  # same ring: nothing sent
    assert cue.updates == n and len(h.sets) == sets
    cue.update(_xpos(box=(0.70, 0.02)), 0, 0.61)  # the box was pushed: the ring follows
    assert h.position[:2] == pytest.approx((0.70, 0.02))
    cue.update(_xpos(), 1, 0.9)  # the robot now predicts the bottle
    assert cue.visible_goal == 1 and h.position[:2] == pytest.approx((0.55, -0.08))
    assert h.scale[0] * 0.72 == pytest.approx(0.03 + 0.012)
    cue.update(_xpos(), 1, 0.05)
    assert cue.visible_goal is None and h.visible is False
    cue.update(_xpos(), 7, 0.9)  # not a goal index: hidden
    assert cue.visible_goal is None
    cue.suppressed = True  # the page benchmark's "off" windows
    cue.update(_xpos(), 0, 0.9)
    assert cue.visible_goal is None
    cue.suppressed = False
    cue.update(_xpos(), 0, 0.9)
    assert cue.visible_goal == 0 and h.visible is True


def _with_mode(text: str, table: str) -> str:
    return re.sub(
        r"\[modes\.aggressive_shown\]\n.*?\nintent = \"goal\"",
        f"[modes.aggressive_shown]\n{table}",
        text,
        flags=re.S,
    )


def test_intent_protocol_turns_the_display_on_per_mode() -> None:
    p = load_protocol(INTENT)
    assert [(m.name, m.intent) for m in p.modes] == [
        ("aggressive", "none"),
        ("aggressive_shown", "goal"),
    ]
    assert p.trial_config("easy-wrong", "aggressive_shown").extra["intent"] == "goal"
    assert p.trial_config("easy-wrong", "aggressive").extra["intent"] == "none"
    assert p.training_config().extra["intent"] == "none"
    assert p.mode("aggressive").arbitration == p.mode("aggressive_shown").arbitration
    design = Design.from_protocol(p)
    assert design.cycle == 8 and p.study.participants % design.cycle == 0
    assert "aggressive_shown" in p.condition_words  # never in participant text or the wire


def test_intent_option_errors_name_the_key_and_the_choices() -> None:
    text = INTENT.read_text(encoding="utf-8")
    bad = _with_mode(
        text, 'arbitration = { kind = "aggressive", threshold = 0.4 }\nintent = "arrow"'
    )
    with pytest.raises(ProtocolValueError, match=r"modes\.aggressive_shown\.intent.*none, goal"):
        parse_protocol(bad)
    none = _with_mode(text, 'arbitration = { kind = "none" }\nintent = "goal"')
    with pytest.raises(ProtocolValueError, match="unassisted mode has no intent"):
        parse_protocol(none)

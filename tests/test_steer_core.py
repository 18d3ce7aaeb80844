"""The open hand's compiled steering equals the trial's Python steering, tick by tick (issue 24.1).

``app.teleop.steer_core.steer`` runs the lift-out rule and the descent guard's hold and palm
stop in one compiled call (``Steering.steer``, ``app.trial.steering``); ``Steering.reference``
is the reference. On every tick of whole trials -- an aggressive robot that is wrong (the
hand lifted out of the object it went down around), a hand lowered beside and over the
practice mug (held above it, stopped by the palm, resting on it) -- both are run from the same state and must steer to the same target, keep
the same guard state and name the same object the hand rests on, bit for bit.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.teleop import ScriptedInput
from app.teleop.lift_out import lift_out
from app.teleop.steer_core import hypot2
from app.trial import Trial
from app.trial import steering as steering_module
from benchmarks.rim_descent import LowerBeside
from study.protocol import load_protocol, trial_config_from_protocol

ROOT = Path(__file__).resolve().parents[1]


def test_hypot2_is_math_hypot_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    scale = rng.choice([1e-6, 1e-3, 1e-2, 0.1, 1.0, 10.0], size=(100_000, 1))
    pairs = (rng.normal(size=(100_000, 2)) * scale).tolist()
    pairs += [(0.0, 0.0), (0.0, -0.3), (0.25, 0.25), (-1e-300, 1e-300), (3.0, 4.0)]
    for a, b in pairs:
        assert hypot2(a, b) == math.hypot(a, b), (a, b)
    assert hypot2(math.inf, 1.0) == math.inf and math.isnan(hypot2(math.nan, 1.0))


def _same(a: Any, b: Any) -> bool:
    """Equal, NaN equal to NaN (the guard's state, the trial's last height)."""
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))


def _checker(trial: Trial, seen: Counter[str]) -> Any:
    """``trial.steering.steer`` (compiled) that also runs the reference from the same state, asserts
    they agree and counts what the reference did."""
    steering = trial.steering
    assert steering.consts is not None  # the compiled steering is the trial's
    compiled = steering.steer

    def counted_lift_out(*args: Any, **kw: Any) -> Any:
        out = lift_out(*args, **kw)
        seen["lifted"] += out is not None
        return out

    def checked(*args: Any) -> np.ndarray:
        target = args[1]
        guard_before = copy.copy(steering.guard)
        offset_before = steering.resting_offset
        last_before = float(steering.state[7])
        got = compiled(*args)
        got_state = (
            steering.guard.state(),
            float(steering.state[7]),
            steering.resting_on,
            steering.resting_centred,
            steering.resting_offset,
        )
        guard_compiled = steering.guard
        steering.guard = guard_before  # the reference from the very same state
        steering._last_ee_z = last_before
        steering.resting_on, steering.resting_centred = None, False
        steering.resting_offset = offset_before
        want = steering.reference(*args)
        want_state = (
            steering.guard.state(),
            steering._last_ee_z,
            steering.resting_on,
            steering.resting_centred,
            steering.resting_offset,
        )
        assert _same(got_state, want_state), (trial.ticks, got_state, want_state)
        if want is target:
            assert got is target, (trial.ticks, got)
        else:
            seen["steered"] += 1
            assert got is not target and np.array_equal(got, want), (got, want)
        seen["held"] += steering.guard.held is not None
        seen["palm_on"] += steering.guard.palm_on is not None
        seen["resting"] += steering.resting_on is not None
        seen["centred"] += steering.resting_centred
        steering.guard = guard_compiled
        seen["ticks"] += 1
        return got

    return checked, counted_lift_out


def _check_every_tick(trial: Trial, seen: Counter[str]) -> None:
    """Run ``trial`` to its end, each tick's steering compiled and by the reference from the
    same state; assert they agree; count what the reference did."""
    checked, counted_lift_out = _checker(trial, seen)
    trial.steering.steer = checked  # type: ignore[method-assign]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(steering_module, "lift_out", counted_lift_out)
        while not trial.done:
            trial.tick()


def test_compiled_steering_equals_the_reference_on_every_tick_of_an_aggressive_wrong_robot() -> (
    None
):
    """The hand lifted out of the wrong object before it goes across (``lift_out``)."""
    seen: Counter[str] = Counter()
    for task in ("easy-wrong", "hard-wrong"):
        config = trial_config_from_protocol(
            ROOT / "protocols" / "dragan2013.toml", task, "aggressive"
        )
        config = dataclasses.replace(config, time_limit_s=12.0)
        for seed in (0, 1):
            _check_every_tick(Trial(config, ScriptedInput(seed=seed), seed=seed), seen)
    assert seen["ticks"] > 1000 and seen["lifted"] > 0, seen


@pytest.mark.parametrize("offset_m", [0.01, 0.035, 0.055])
def test_compiled_steering_equals_the_reference_lowering_beside_and_over_the_mug(
    offset_m: float,
) -> None:
    """Held above the mug (3.5 cm off across the slot), the palm's stop over and beside it,
    the hand resting on it (1 cm off: it goes down around it; 5.5 cm along the slot: beside)."""
    seen: Counter[str] = Counter()
    config = load_protocol(ROOT / "protocols" / "dragan2013.toml").training_config()
    config = dataclasses.replace(config, time_limit_s=10.0)
    for axis in (0, 1):
        trial = Trial(config, IdleBeside.build(config, offset_m, axis))
        _check_every_tick(trial, seen)
    assert seen["ticks"] > 1000 and seen["steered"] > 0 and seen["resting"] > 0, seen
    if offset_m == 0.035:
        assert seen["held"] > 0, seen
    if offset_m == 0.01:
        assert seen["palm_on"] > 0 and seen["centred"] > 0, seen


def test_compiled_steering_equals_the_reference_lowering_beside_the_bottle() -> None:
    """The open hand lowered 6.3 cm off the tall bottle's axis along the slot: lifted out of
    it, stopped above it by the palm or the wrist's part above the palm."""
    seen: Counter[str] = Counter()
    config = trial_config_from_protocol(
        ROOT / "protocols" / "dragan2013.toml", "easy-right", "none"
    )
    config = dataclasses.replace(config, time_limit_s=10.0)
    _check_every_tick(Trial(config, IdleBeside.build(config, 0.063, 0, tallest=True)), seen)
    assert seen["ticks"] == 1000 and seen["lifted"] > 0 and seen["palm_on"] > 0, seen


class IdleBeside:
    """``benchmarks.rim_descent.LowerBeside`` for a scene of ``config``."""

    @staticmethod
    def build(config: Any, offset_m: float, axis: int, *, tallest: bool = False) -> LowerBeside:
        trial = Trial(config, ScriptedInput(), keep_records=False)
        k = trial.scene.target_index
        if tallest:
            footprints = trial.steering.footprints
            k = max(range(len(footprints)), key=lambda i: footprints[i][3])
        offset = np.zeros(3)
        offset[axis] = offset_m
        return LowerBeside(trial.scene.goals.positions[k].copy(), offset)


def test_compiled_steering_equals_the_reference_on_random_states() -> None:
    """6,000 random scenes of one to three objects side by side, the hand and the target
    around them, every guard state (held, let go of, settling, palm on, palm left), the
    robot's goal and fallen objects: every branch of the rules, thresholds within reach."""
    config = load_protocol(ROOT / "protocols" / "dragan2013.toml").training_config()
    trial = Trial(config, ScriptedInput(), keep_records=False)
    steering = trial.steering
    seen: Counter[str] = Counter()
    checked, counted_lift_out = _checker(trial, seen)
    rng = np.random.default_rng(11)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(steering_module, "lift_out", counted_lift_out)
        for _ in range(6000):
            n = int(rng.integers(1, 4))
            radius = rng.uniform(0.015, 0.05, n)
            objects = tuple(
                (
                    0.4 + 0.1 * k + rng.normal(0, 0.01),
                    rng.normal(0, 0.02),
                    r,
                    rng.uniform(0.05, 0.25),
                    rng.uniform(0.005, r),
                )
                for k, r in enumerate(radius.tolist())
            )
            k = int(rng.integers(n))
            ox, oy, _, top, _ = objects[k]
            spread = np.c_[rng.normal(0, 0.04, (2, 2)), rng.uniform(-0.1, 0.2, 2)]
            ee, target = np.array((ox, oy, top)) + spread  # the hand, the target
            steering.footprints = objects
            steering.cylinders = tuple(o[:4] for o in objects)
            steering.rows = steering_module.rows(objects)
            alpha, predicted = float(rng.choice([0.0, 0.6])), int(rng.integers(n))
            taking = predicted if alpha > 0.0 else -1  # the robot's goal, while it acts
            fallen = tuple(j for j in range(n) if rng.uniform() < 0.15)
            now = int(rng.integers(0, 1000)) * trial._dt
            held, cleared, palm_on, palm_left = rng.choice([-1.0, k, k, rng.integers(n)], 4)
            since = (now - rng.uniform(0, 0.3), ee[0] + rng.normal(0, 0.004), ee[1])
            if rng.uniform() < 0.5:
                since = (math.nan,) * 3
            steering.guard.set_state((held, cleared, *since, palm_on, palm_left))
            steering.synced = False
            steering.state[7] = ee[2] + float(rng.choice([0.0, 1e-4, 0.01]))
            steering.resting_on, steering.resting_centred = None, False
            checked(ee.copy(), target.copy(), taking, fallen, now)
    assert seen["ticks"] == 6000
    for what in ("lifted", "held", "palm_on", "steered"):
        assert seen[what] > 500, seen
    assert seen["resting"] > 50 and seen["centred"] > 0, seen

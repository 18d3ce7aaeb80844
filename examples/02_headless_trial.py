"""One headless trial from the shipped protocol, and its outcome.

Shows the whole control loop without a browser: ``protocols/dragan2013.toml`` is loaded and
validated, one condition (the hard task with a correct prediction, aggressive assistance) becomes
an ``app.trial.TrialConfig``, and a scripted user (a noisy reach toward the target, then a
grasp and a lift) drives the simulated Franka Panda through input -> blending -> robot, tick by
tick, as fast as the machine allows. The same loop runs a participant's trial in the browser.

Run: ``python examples/02_headless_trial.py``
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from app.teleop import ScriptedInput
from app.trial.trial import run_trial
from study.protocol import load_protocol

PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "dragan2013.toml"


def main() -> None:
    protocol = load_protocol(PROTOCOL)
    config = protocol.trial_config("hard-right", "aggressive")
    user = ScriptedInput(seed=1, speed=0.15, noise=0.002)

    wall = time.perf_counter()
    result = run_trial(config, user, seed=1)
    wall = time.perf_counter() - wall

    print(f"protocol {protocol.id}: task {config.task}, mode {config.mode}")
    print(f"outcome: {result.outcome} after {result.duration_s:.2f} s simulated")
    print(f"{result.ticks} control ticks at {config.rate_hz:g} Hz in {wall:.2f} s of wall time")
    alphas = [r.alpha for r in result.records]
    print(f"target {result.target}; mean alpha {np.mean(alphas):.3f}, max {max(alphas):.3f}")


if __name__ == "__main__":
    main()

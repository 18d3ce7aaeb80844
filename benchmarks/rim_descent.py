"""The open hand lowered beside an object's axis: does the object stay standing?

A participant who lowers the open gripper a couple of centimetres off the object's axis,
across the fingers' slot (world y), puts a fingertip on its rim. For each offset the script
runs the practice run headless (the paper protocol's mug, no assistance): the user's target
goes 10 cm above the point ``offset`` off the grasp point, then 2 cm below the grasp point's
height there and stays (F held), for ``--seconds``. Printed per offset: the fingers' contacts
with the object, the hand's height range over the last half (a hand hopping on the rim shows
a range of centimetres), how far the object moved, and whether it was knocked or pushed
(``Trial.accidents``). A grasping robot a person can trust leaves the object standing at every
offset; at 0 the object sits between the fingers.

Usage: ``.venv/bin/python benchmarks/rim_descent.py [--offsets 0,0.01,0.02,0.025,0.03,0.035,0.045]
[--seconds 15] [--axis y]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.robot import build_scene  # noqa: E402
from app.teleop.types import TeleopCommand, TrialObservation  # noqa: E402
from app.trial import Trial  # noqa: E402
from app.trial.events import EventKind  # noqa: E402
from study.protocol import load_protocol  # noqa: E402


class LowerBeside:
    """Above the point ``offset`` off the grasp point (along ``axis``), then down and held."""

    def __init__(self, grasp: np.ndarray, offset: np.ndarray) -> None:
        self.above = grasp + offset + np.array((0.0, 0.0, 0.10))
        self.low = grasp + offset + np.array((0.0, 0.0, -0.02))
        self.lowering = False

    def command(self, obs: TrialObservation) -> TeleopCommand:
        if not self.lowering and np.linalg.norm(obs.ee - self.above) < 0.005:
            self.lowering = True
        return TeleopCommand(target=(self.low if self.lowering else self.above).copy())


def run(offset_m: float, *, axis: int, seconds: float) -> dict:
    config = load_protocol(ROOT / "protocols" / "dragan2013.toml").training_config()
    config = dataclasses.replace(config, time_limit_s=seconds + 10.0)
    scene = build_scene(config.scene)
    k = scene.target_index
    offset = np.zeros(3)
    offset[axis] = offset_m
    user = LowerBeside(scene.goals.positions[k].copy(), offset)
    trial = Trial(config, user, scene=scene)
    start = trial.sim.object_positions()[k].copy()
    heights: list[tuple[float, float]] = []
    lowered_at = None
    while not trial.done and (lowered_at is None or trial.t < lowered_at + seconds):
        trial.tick()
        if user.lowering and lowered_at is None:
            lowered_at = trial.t
        if lowered_at is not None:
            heights.append((trial.t - lowered_at, float(trial.sim.ee[2])))
    z = np.array([h for t, h in heights if t > seconds / 2]) if heights else np.zeros(1)
    contacts = sum(
        1 for _, e in trial.events if e.kind is EventKind.CONTACT and e.obj == scene.object_names[k]
    )
    moved = float(np.linalg.norm(trial.sim.object_positions()[k][:2] - start[:2]))
    return {
        "offset_m": offset_m,
        "contacts": contacts,
        "hand_z_range_m": round(float(z.max() - z.min()), 3),
        "hand_z_end_m": round(float(trial.sim.ee[2]), 3),
        "object_moved_m": round(moved, 3),
        "knocked_or_pushed": trial.accidents.count,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--offsets", default="0,0.01,0.02,0.025,0.03,0.035,0.045")
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--axis", choices=("x", "y"), default="y", help="y: across the slot")
    args = parser.parse_args()
    rows = [
        run(float(o), axis="xy".index(args.axis), seconds=args.seconds)
        for o in args.offsets.split(",")
    ]
    for row in rows:
        print(json.dumps(row))
    knocked = sum(1 for r in rows if r["knocked_or_pushed"])
    print(f"objects knocked or pushed: {knocked} of {len(rows)} offsets along {args.axis}")


if __name__ == "__main__":
    main()

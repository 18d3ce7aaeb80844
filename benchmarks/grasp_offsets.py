"""The gripper closed beside an object's axis along its slot: is the object held?

A participant closes the gripper where they see the object between the fingers, often a
centimetre or two off its axis along the slot (world x). For each offset the script runs the
practice run headless (the paper protocol's mug, no assistance): the user's target goes to the
point ``offset`` off the grasp point (``--dz`` above it), G once the TCP is within 3 mm and
0.5 s later. A lifted mug is then carried (``carry``: the TCP ``CARRY`` further at ``CARRY_SPEED``,
the gripper closed). Printed per offset: the outcome, the time, the grasp's events, how far the
mug moved on the table, its fastest speed, and after the carry whether it is still held and how
far it slipped in the hand. The 17.6-mm finger pads still cover the mug's axis up to about 1 cm
off; a real hand holds a cylinder well beyond that (the pad's contact normal within the
friction cone).

Usage: ``.venv/bin/python benchmarks/grasp_offsets.py [--offsets 0,0.01,0.015,0.02,0.025,0.03]
[--dz 0]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
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

GRASP_EVENTS = (
    EventKind.GRASPED,
    EventKind.GRASP_MISSED,
    EventKind.DROPPED,
    EventKind.KNOCKED_OVER,
)
CARRY = np.array([0.0, 0.15, 0.10])  # m: across the table and up, after the lift
CARRY_SPEED = 0.2  # m/s, twice the automatic lift's


class GraspAt:
    """To ``point``, then G half a second after the TCP is within 3 mm of it."""

    def __init__(self, point: np.ndarray) -> None:
        self.point = point
        self.there: float | None = None

    def command(self, obs: TrialObservation) -> TeleopCommand:
        if self.there is None and np.linalg.norm(obs.ee - self.point) < 0.003:
            self.there = obs.t
        grasp = self.there is not None and obs.t > self.there + 0.5
        return TeleopCommand(target=self.point.copy(), grasp=grasp)


def grasp_trial(offset_m: float, *, dz: float = 0.0, seconds: float = 15.0) -> Trial:
    """The practice run with the user's grasp ``offset_m`` along the slot, ``dz`` above."""
    config = load_protocol(ROOT / "protocols" / "dragan2013.toml").training_config()
    config = dataclasses.replace(config, time_limit_s=seconds)
    scene = build_scene(config.scene)
    point = scene.goals.positions[scene.target_index] + np.array([offset_m, 0.0, dz])
    return Trial(config, GraspAt(point), scene=scene)


def carry(trial: Trial, *, shift: np.ndarray = CARRY, speed: float = CARRY_SPEED) -> dict:
    """After a lift, the TCP ``shift`` further at ``speed`` with the gripper closed: whether
    the target is still held (both fingers on it), its slip in the hand and its tilt."""
    sim, k = trial.sim, trial.scene.target_index
    in_hand = sim.object_positions()[k] - sim.ee
    goal = sim.ee + shift
    ticks = math.ceil(float(np.linalg.norm(shift)) / speed * trial.config.rate_hz) + 50
    for _ in range(ticks):
        command = trial.ik(sim.q, goal, max_speed=speed)
        sim.step(command, gripper_closed=True, substeps=trial.config.substeps)
    return {
        "held": sim.held_object() == k,
        "slip_m": round(float(np.linalg.norm(sim.object_positions()[k] - sim.ee - in_hand)), 4),
        "tilt_deg": round(math.degrees(float(sim.object_tilts()[k])), 1),
        "tcp_off_m": round(float(np.linalg.norm(sim.ee - goal)), 4),
    }


def run(offset_m: float, *, dz: float, seconds: float = 15.0) -> dict:
    trial = grasp_trial(offset_m, dz=dz, seconds=seconds)
    k = trial.scene.target_index
    start = trial.sim.object_positions()[k].copy()
    body = trial.scene.object_body_ids[k]
    fastest = 0.0
    while not trial.done:
        trial.tick()
        fastest = max(fastest, float(np.linalg.norm(trial.sim.data.cvel[body, 3:])))
    moved = float(np.linalg.norm(trial.sim.object_positions()[k][:2] - start[:2]))
    row = {
        "offset_m": offset_m,
        "outcome": trial.outcome,
        "t_s": round(trial.t, 2),
        "events": [e.kind.value for _, e in trial.events if e.kind in GRASP_EVENTS],
        "object_moved_m": round(moved, 3),
        "fastest_m_s": round(fastest, 2),
    }
    if trial.outcome == "success":
        row["carry"] = carry(trial)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--offsets", default="0,0.01,0.015,0.02,0.025,0.03")
    parser.add_argument(
        "--dz",
        type=float,
        default=0.0,
        help="above the grasp point (m); below it the palm stop (2.4 mm under) holds the hand",
    )
    args = parser.parse_args()
    rows = [run(float(o), dz=args.dz) for o in args.offsets.split(",")]
    for row in rows:
        print(json.dumps(row))
    lifted = sum(1 for r in rows if r["outcome"] == "success")
    carried = sum(1 for r in rows if r.get("carry", {}).get("held"))
    print(
        f"lifted: {lifted} of {len(rows)} offsets along the slot; still held after the carry: {carried}"
    )


if __name__ == "__main__":
    main()

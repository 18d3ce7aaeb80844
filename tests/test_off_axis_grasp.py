"""The gripper closed beside the mug's axis along the slot holds it, as a real gripper does.

A participant closes the gripper where they see the mug between the fingers, often 1-3 cm off
its axis along the slot (world x; the pads are 17.6 mm wide). A real parallel gripper holds a
5.6-cm cylinder there (the pad's contact normal within the friction cone); in MuJoCo the pad's
box edge squeezed the mug out sideways (``benchmarks/grasp_offsets.py``, README "A grasp closed
off the object's axis along the slot"), which the capsules of ``app.robot.arm._pad_capsules`` fix.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.trial.events import EventKind
from benchmarks.grasp_offsets import carry, grasp_trial


@pytest.mark.parametrize(("offset_m", "dz"), [(0.02, 0.0), (0.02, 0.01), (0.01, 0.0)])
def test_the_mug_closed_on_off_its_axis_along_the_slot_is_lifted_and_carried(
    offset_m: float, dz: float
) -> None:
    """At the grasp height and 1 cm above it (``dz``), 1 and 2 cm off the axis."""
    trial = grasp_trial(offset_m, dz=dz, seconds=6.0)
    while not trial.done:
        trial.tick()
    assert trial.outcome == "success"
    assert [e.kind for _, e in trial.events if e.kind is EventKind.GRASPED] == [EventKind.GRASPED]
    held = carry(trial)  # 15 cm across the table and 10 cm up at 0.2 m/s
    assert held["held"] and held["slip_m"] < 0.005 and held["tilt_deg"] < 5.0


def test_closed_3_cm_off_its_axis_the_mug_may_slip_out_but_is_not_flung() -> None:
    trial = grasp_trial(0.03, seconds=6.0)
    body = trial.scene.object_body_ids[trial.scene.target_index]
    fastest = 0.0
    while not trial.done:
        trial.tick()
        fastest = max(fastest, float(np.linalg.norm(trial.sim.data.cvel[body, 3:])))
    assert fastest < 1.5  # m/s: at most a 10-cm mug tipping over, never thrown off the table

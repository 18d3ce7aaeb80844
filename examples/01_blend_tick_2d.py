"""One blending tick in 2-D with a custom arbitration function.

Shows the formalism of Dragan & Srinivasa (2013) on a point robot in the plane, without the
arm: the user's next configuration U moves toward one of two goals; the robot predicts the goal
from the motion so far (amnesic predictor, eq. 8-style softmax over goal costs), takes its
confidence c = P(G* | xi), maps it to alpha with *our own* arbitration function and blends

    command = (1 - alpha) U + alpha P,

where P is the robot's policy: a straight step toward the predicted goal. The custom
arbitration is an ordinary function c -> alpha, wrapped in ``FunctionArbitration``, which checks
at construction that it maps [0, 1] into [0, 1] without decreasing.

Run: ``python examples/01_blend_tick_2d.py``
"""

from __future__ import annotations

import numpy as np

from app.blending import (
    AmnesicPredictor,
    FunctionArbitration,
    GoalSet,
    PolicyBlender,
    ProbabilityConfidence,
    StraightLinePolicy,
)


def smooth_step(c: float) -> float:
    """No help below c = 0.5, then a smooth ramp up to alpha = 0.8 at c = 1."""
    t = min(max((c - 0.5) / 0.5, 0.0), 1.0)
    return 0.8 * t * t * (3.0 - 2.0 * t)


def main() -> None:
    # two goals in the plane (configurations are 2-D; positions carry z = 0)
    configurations = np.array([[1.0, 0.2], [1.0, -0.6]])
    goals = GoalSet(
        ["cup", "can"],
        np.c_[configurations, np.zeros(2)],
        configurations=configurations,
    )
    blender = PolicyBlender(
        goals=goals,
        predictor=AmnesicPredictor(configurations, temperature=0.1),
        confidence=ProbabilityConfidence(),
        arbitration=FunctionArbitration(smooth_step, breakpoints=(0.5,)),
        policy=StraightLinePolicy(max_step=0.05),
        space="configuration",
    )
    start = np.zeros(2)
    blender.reset(start)  # S: where the user's motion started

    q = np.array([0.6, 0.1])  # the robot's configuration Q now
    u = np.array([0.65, 0.13])  # the user's next configuration U (heading up-right)
    record = blender.step(q, u)

    goal = goals.names[record.predicted]
    probabilities = {
        n: round(float(p), 3) for n, p in zip(goals.names, record.probabilities, strict=True)
    }
    print(f"P(goal | motion): {probabilities}")
    print(f"predicted goal:   {goal}")
    print(f"confidence c:     {record.confidence:.3f}")
    print(f"alpha(c):         {record.alpha:.3f}  (custom arbitration: smooth_step)")
    print(f"user U:           {u}")
    print(f"policy P:         {np.round(record.P, 4)}")
    print(f"command:          {np.round(record.command, 4)}")
    expected = (1.0 - record.alpha) * u + record.alpha * record.P
    assert np.allclose(record.command, expected), "command = (1 - alpha) U + alpha P"


if __name__ == "__main__":
    main()

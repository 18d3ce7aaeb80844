"""Compile the control tick's kernels before a session needs them: ``python -m app.warm_up``.

numba compiles a kernel at its first call (about 6 s for all of them on the reference machine)
and keeps the machine code in ``app/__pycache__/numba-<hash of the kernels' sources>``;
later processes load it (about
0.2 s). :func:`warm_up` makes that first call on dummy inputs, so a study server's first tick
does not wait for it, and CI's setup runs it once before the test workers start.
"""

from __future__ import annotations

import time

from app.blending import policy_grasp_core
from app.robot import kinematics_core
from app.teleop import ik_step_core, steer_core
from app.trial import fused_control_core

__all__ = ["warm_up"]


def warm_up() -> float:
    """Compile (or load) every kernel of the control tick; the seconds it took."""
    start = time.perf_counter()
    policy_grasp_core.warm_up()
    ik_step_core.warm_up()
    kinematics_core.warm_up()
    fused_control_core.warm_up()
    steer_core.warm_up()
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"the control tick's kernels ready in {warm_up():.2f} s")

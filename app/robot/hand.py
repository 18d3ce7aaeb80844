"""The hand's collision parts as boxes in the TCP frame, for a policy that keeps them clear.

``hand_layers(model, tcp_site_id, opening=...)`` reads the compiled MuJoCo model: every
colliding geom of the wrist, hand and fingers (``LOW_LINKS``; the upper links collide with
nothing) is put in the TCP frame at ``q_7 = 0`` with the fingers at ``opening``, and becomes a
:class:`app.blending.policy_grasp.HandLayer`: the bounding box of its vertices (meshes) or of
its own bounding box (primitives), heights measured up from the TCP along the approach axis.
The two fingers make one layer; ``panda_link6`` sits before the last joint, so its layer turns
with ``q_7`` about the TCP axis (the joint's axis passes through the TCP).
"""

from __future__ import annotations

import mujoco
import numpy as np

from app.blending.policy_grasp import HandLayer
from app.robot.arm import ARM_JOINTS, LOW_LINKS
from app.robot.errors import SceneError

TURNING_LINK = "panda_link6"
"""The collision link before the last joint."""
FINGERS = ("panda_leftfinger", "panda_rightfinger")


def hand_layers(
    model: mujoco.MjModel, tcp_site_id: int, *, opening: float
) -> tuple[HandLayer, ...]:
    """The hand's collision layers, fingers first (see the module's docstring)."""
    data = mujoco.MjData(model)
    lo = model.jnt_range[[model.joint(n).id for n in ARM_JOINTS], 0]
    hi = model.jnt_range[[model.joint(n).id for n in ARM_JOINTS], 1]
    q = 0.5 * (lo + hi)
    q[-1] = 0.0
    data.qpos[: len(ARM_JOINTS)] = q
    for name in FINGERS:
        data.qpos[model.jnt_qposadr[model.body(name).jntadr[0]]] = opening
    mujoco.mj_kinematics(model, data)
    tcp = data.site_xpos[tcp_site_id].copy()
    rot = data.site_xmat[tcp_site_id].reshape(3, 3).copy()
    finger_points: list[np.ndarray] = []
    layers: list[HandLayer] = []
    for g in range(model.ngeom):
        body = model.body(model.geom_bodyid[g]).name
        if body not in LOW_LINKS or (model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0):
            continue
        local = (_vertices(model, data, g) - tcp) @ rot  # rows in the TCP frame
        if body in FINGERS:
            finger_points.append(local)
        else:
            layers.append(_layer(local, turns=body == TURNING_LINK))
    if not finger_points:  # pragma: no cover - the Panda has fingers
        raise SceneError("hand_layers: the model has no colliding finger geoms")
    return (_layer(np.vstack(finger_points), turns=False), *layers)


def _vertices(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """World coordinates of the geom's mesh vertices, or of its bounding box's corners."""
    if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[g]
        start = model.mesh_vertadr[mesh]
        local = model.mesh_vert[start : start + model.mesh_vertnum[mesh]]
    else:
        center, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        local = center + signs * half
    return data.geom_xpos[g] + local @ data.geom_xmat[g].reshape(3, 3).T


def _layer(points: np.ndarray, *, turns: bool) -> HandLayer:
    lo_xyz, hi_xyz = points.min(axis=0), points.max(axis=0)
    center = 0.5 * (lo_xyz + hi_xyz)
    half = 0.5 * (hi_xyz - lo_xyz)
    # the TCP's z axis points along the approach (down for top-down grasps): up is -z
    return HandLayer(
        lo=float(-hi_xyz[2]),
        hi=float(-lo_xyz[2]),
        center=(float(center[0]), float(center[1])),
        half=(float(half[0]), float(half[1])),
        turns=turns,
    )

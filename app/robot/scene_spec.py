"""A scene as plain, validated data: table, objects, target, start configuration, reach region.

``SceneSpec.from_dict(d, where="scenes.easy")`` reads one ``[scenes.*]`` table of a protocol;
every error names the key path and says what to change. Every number is finite and within a
range a tabletop scene can have, the start configuration within the Panda's joint limits
(:data:`JOINT_LIMITS`), every object on the table and apart from the others. Geometry that
needs the arm model (grasp poses, goal configurations by IK, reachability) is checked by
``build_scene``, which the commands run for every scene before a session starts.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from app.robot.errors import SceneError

SHAPES = {
    "cylinder": 2,
    "box": 3,
}  # shape -> number of size entries (radius, half-height) / half-extents
_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")
ARM_DOF = 7
JOINT_LIMITS: tuple[tuple[float, float], ...] = (
    (-2.8973, 2.8973),
    (-1.7628, 1.7628),
    (-2.8973, 2.8973),
    (-3.0718, -0.0698),
    (-2.8973, 2.8973),
    (-0.0175, 3.7525),
    (-2.8973, 2.8973),
)
"""The Panda's joint limits in radians, as its URDF gives them (a test checks they match the
loaded model), so a protocol is checked without loading the arm."""
WORKSPACE_M = 2.0
"""No scene coordinate (table, objects, reach) lies farther than this from the robot's base."""


@dataclass(frozen=True)
class ObjectSpec:
    """A graspable object resting on the table.

    ``size``: cylinder ``(radius, half_height)``, box ``(hx, hy, hz)`` half-extents, metres.
    ``position``: centre of the object in the world frame; ``yaw`` about world z, radians.
    """

    name: str
    shape: str
    size: tuple[float, ...]
    position: tuple[float, float, float]
    yaw: float = 0.0
    mass: float = 0.1
    rgba: tuple[float, float, float, float] = (0.2, 0.5, 0.8, 1.0)

    @property
    def half_height(self) -> float:
        return self.size[1] if self.shape == "cylinder" else self.size[2]

    @property
    def footprint_radius(self) -> float:
        """Radius of a circle on the table that contains the object's footprint."""
        if self.shape == "cylinder":
            return self.size[0]
        return math.hypot(self.size[0], self.size[1])

    @property
    def grasp_width(self) -> float:
        """Width across the gripper's closing direction when grasped (gripper along world y)."""
        return (
            2.0 * self.size[0]
            if self.shape == "cylinder"
            else 2.0 * min(self.size[0], self.size[1])
        )


@dataclass(frozen=True)
class TableSpec:
    """A box table whose top is at ``top_z``; ``center``/``half_size`` in the xy plane."""

    center: tuple[float, float] = (0.55, 0.0)
    half_size: tuple[float, float] = (0.4, 0.6)
    top_z: float = 0.0
    thickness: float = 0.04


@dataclass(frozen=True)
class SceneSpec:
    """Everything needed to build a scene: objects, which one is the target, where the arm starts.

    ``reach_lo``/``reach_hi`` bound the region the interface lets the user point at (an
    axis-aligned box, world frame); ``start_q`` is the arm's initial configuration (7,).
    """

    name: str
    target: str
    start_q: tuple[float, ...]
    reach_lo: tuple[float, float, float]
    reach_hi: tuple[float, float, float]
    objects: tuple[ObjectSpec, ...]
    table: TableSpec = field(default_factory=TableSpec)
    gripper_open: float = 0.04
    contacts: str = "always"
    """``always``: the arm touches objects at all times; ``grasp``: only the closing fingers do
    (the arm passes through objects while reaching; the platform's earlier behaviour)."""

    @property
    def object_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.objects)

    def object(self, name: str) -> ObjectSpec:
        for o in self.objects:
            if o.name == name:
                return o
        raise SceneError(
            f"scene {self.name!r} has no object {name!r}; objects: {self.object_names}"
        )

    @property
    def target_index(self) -> int:
        return self.object_names.index(self.target)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, where: str = "scene") -> SceneSpec:
        """Validate one ``[scenes.NAME]`` table; ``where`` is its key path for error messages."""
        if not isinstance(d, Mapping):
            raise SceneError(f"{where}: expected a table, got {type(d).__name__}")
        known = {
            "target",
            "start_q",
            "reach",
            "objects",
            "table",
            "gripper_open",
            "name",
            "contacts",
        }
        unknown = sorted(set(d) - known)
        if unknown:
            raise SceneError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(known)}")
        for key in ("target", "start_q", "reach", "objects"):
            if key not in d:
                raise SceneError(f"{where}.{key}: missing (required)")
        name = str(d.get("name", where.rsplit(".", 1)[-1]))
        start_q = _floats(d["start_q"], f"{where}.start_q", n=ARM_DOF, bound=4.0)
        outside = [
            f"joint {k + 1} = {q:.4f} not in [{lo}, {hi}]"
            for k, (q, (lo, hi)) in enumerate(zip(start_q, JOINT_LIMITS, strict=True))
            if not lo <= q <= hi
        ]
        if outside:
            raise SceneError(
                f"{where}.start_q: outside the Panda's joint limits ({'; '.join(outside)})"
            )
        reach = d["reach"]
        if not isinstance(reach, Mapping) or set(reach) != {"min", "max"}:
            raise SceneError(f"{where}.reach: expected {{ min = [x, y, z], max = [x, y, z] }}")
        lo = _floats(reach["min"], f"{where}.reach.min", n=3, bound=WORKSPACE_M)
        hi = _floats(reach["max"], f"{where}.reach.max", n=3, bound=WORKSPACE_M)
        if any(a >= b for a, b in zip(lo, hi, strict=True)):
            raise SceneError(f"{where}.reach: min {lo} must be below max {hi} on every axis")
        raw_objects = d["objects"]
        if not isinstance(raw_objects, Sequence) or isinstance(raw_objects, str) or not raw_objects:
            raise SceneError(f"{where}.objects: expected a non-empty list of object tables")
        objects = tuple(_object(o, f"{where}.objects[{i}]") for i, o in enumerate(raw_objects))
        names = [o.name for o in objects]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise SceneError(f"{where}.objects: duplicate object name(s) {dupes}")
        target = d["target"]
        if target not in names:
            raise SceneError(f"{where}.target: {target!r} is not one of the objects {names}")
        table = _table(d.get("table", {}), f"{where}.table")
        gripper_open = _number(d.get("gripper_open", 0.04), f"{where}.gripper_open", 0.001, 0.04)
        contacts = d.get("contacts", "always")
        if contacts not in ("always", "grasp"):
            raise SceneError(
                f"{where}.contacts: {contacts!r}; use 'always' (the arm touches objects) or"
                " 'grasp' (only the closing fingers do)"
            )
        spec = cls(
            name=name,
            target=str(target),
            start_q=start_q,
            reach_lo=lo,  # type: ignore[arg-type]
            reach_hi=hi,  # type: ignore[arg-type]
            objects=objects,
            table=table,
            gripper_open=gripper_open,
            contacts=str(contacts),
        )
        spec._check_layout(where)
        return spec

    def _check_layout(self, where: str) -> None:
        t = self.table
        for i, o in enumerate(self.objects):
            bottom = o.position[2] - o.half_height
            if abs(bottom - t.top_z) > 0.005:
                raise SceneError(
                    f"{where}.objects[{i}] ({o.name!r}): bottom at z={bottom:.3f} m, but the table"
                    f" top is at z={t.top_z:.3f} m; set position z = {t.top_z + o.half_height:.3f}"
                )
            for axis in (0, 1):
                if abs(o.position[axis] - t.center[axis]) + o.footprint_radius > t.half_size[axis]:
                    raise SceneError(f"{where}.objects[{i}] ({o.name!r}): not on the table")
            if o.grasp_width >= 2 * self.gripper_open - 0.005:
                raise SceneError(
                    f"{where}.objects[{i}] ({o.name!r}): {o.grasp_width * 1000:.0f} mm wide, the"
                    f" open gripper spans {2000 * self.gripper_open:.0f} mm; make it narrower"
                )
        for i, a in enumerate(self.objects):
            for j in range(i + 1, len(self.objects)):
                b = self.objects[j]
                gap = math.dist(a.position[:2], b.position[:2])
                if gap < a.footprint_radius + b.footprint_radius + 0.02:
                    raise SceneError(
                        f"{where}.objects: {a.name!r} and {b.name!r} overlap or touch (centres"
                        f" {gap * 100:.1f} cm apart); move them at least 2 cm apart"
                    )


def _floats(value: Any, where: str, *, n: int, bound: float = WORKSPACE_M) -> tuple[float, ...]:
    """``n`` finite numbers, each within ``bound`` of 0."""
    if isinstance(value, str) or not isinstance(value, Sequence) or len(value) != n:
        raise SceneError(f"{where}: expected a list of {n} numbers, got {_short(value)}")
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise SceneError(f"{where}[{i}]: expected a finite number, got {_short(v)}")
        if abs(v) > bound:
            raise SceneError(f"{where}[{i}]: {v} is beyond {bound:g}")
        out.append(float(v))
    return tuple(out)


def _number(value: Any, where: str, lo: float, hi: float) -> float:
    """One finite number in [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SceneError(f"{where}: expected a finite number, got {_short(value)}")
    if not lo <= value <= hi:
        raise SceneError(f"{where}: {value} outside [{lo:g}, {hi:g}]")
    return float(value)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _object(d: Any, where: str) -> ObjectSpec:
    if not isinstance(d, Mapping):
        raise SceneError(f"{where}: expected a table {{ name, shape, size, position }}")
    known = {"name", "shape", "size", "position", "yaw", "mass", "rgba"}
    unknown = sorted(set(d) - known)
    if unknown:
        raise SceneError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(known)}")
    for key in ("name", "shape", "size", "position"):
        if key not in d:
            raise SceneError(f"{where}.{key}: missing (required)")
    name = d["name"]
    if not isinstance(name, str) or not _NAME.match(name):
        raise SceneError(
            f"{where}.name: {name!r} must be lower-case letters, digits, '_' or '-' (max 32)"
        )
    shape = d["shape"]
    if shape not in SHAPES:
        raise SceneError(f"{where}.shape: {shape!r} is not one of {sorted(SHAPES)}")
    size = _floats(d["size"], f"{where}.size", n=SHAPES[shape])
    if any(s <= 0.0 or s > 0.5 for s in size):
        raise SceneError(f"{where}.size: every entry must lie in (0, 0.5] m, got {size}")
    position = _floats(d["position"], f"{where}.position", n=3)
    yaw = _number(d.get("yaw", 0.0), f"{where}.yaw", -2 * math.pi, 2 * math.pi)
    mass = _number(d.get("mass", 0.1), f"{where}.mass", 0.005, 2.0)
    rgba = _floats(d.get("rgba", (0.2, 0.5, 0.8, 1.0)), f"{where}.rgba", n=4, bound=1.0)
    if min(rgba) < 0.0:
        raise SceneError(f"{where}.rgba: every entry must lie in [0, 1], got {rgba}")
    return ObjectSpec(
        name=name,
        shape=shape,
        size=size,
        position=position,  # type: ignore[arg-type]
        yaw=yaw,
        mass=mass,
        rgba=rgba,  # type: ignore[arg-type]
    )


def _table(d: Any, where: str) -> TableSpec:
    if not isinstance(d, Mapping):
        raise SceneError(f"{where}: expected a table {{ center, half_size, top_z }}")
    unknown = sorted(set(d) - {"center", "half_size", "top_z", "thickness"})
    if unknown:
        raise SceneError(f"{where}: unknown key(s) {unknown}")
    default = TableSpec()
    center = _floats(d.get("center", default.center), f"{where}.center", n=2)
    half = _floats(d.get("half_size", default.half_size), f"{where}.half_size", n=2)
    if min(half) <= 0:
        raise SceneError(f"{where}.half_size: must be positive, got {half}")
    top_z = _number(d.get("top_z", default.top_z), f"{where}.top_z", -0.5, 0.5)
    thickness = _number(d.get("thickness", default.thickness), f"{where}.thickness", 0.005, 0.2)
    return TableSpec(center=center, half_size=half, top_z=top_z, thickness=thickness)  # type: ignore[arg-type]

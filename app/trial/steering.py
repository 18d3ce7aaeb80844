"""The open hand's steering around objects: where ``U`` steers each tick of a trial.

The user's target, or first out of an object the open hand is around and the target leaves
(``app.teleop.lift_out``), or held above an object the open hand would come down on rather
than around (``app.teleop.guarded_descent``; ``guard.held`` names it), or no lower than its
palm clears the top of an object it is lowered around (``resting_on`` names it). Not out of
(or above) a lying object, nor out of the one the robot is taking the hand to (``taking``:
its predicted goal while ``alpha > 0``): its policy keeps the hand clear there, and in a Hard
task the user's target, held at the reach's edge, always lies off the object the robot is
carrying the hand to. In one compiled call (``app.teleop.steer_core``) when the hand's numbers
allow it, else by :meth:`Steering.reference`, the reference the compiled call is tested equal
to (``tests/test_steer_core.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from app.blending.policy_grasp import HandLayer
from app.robot.scene import Scene
from app.teleop.guarded_descent import CENTRED_M, DescentGuard, Footprint
from app.teleop.lift_out import CLEARANCE_M, Cylinder, lift_out
from app.teleop.steer_core import CHANGED, RESTING, STEERED, pack_consts, steer


class Steering:
    """The trial's steering around ``scene``'s objects (the hand's fingertips ``reach_below``
    under the TCP, the reach's floor at height ``floor``): :meth:`steer` once per tick,
    :meth:`objects_moved` when the objects move."""

    def __init__(self, scene: Scene, *, reach_below: float, floor: float) -> None:
        self.guard = descent_guard(scene, reach_below)
        """Holds the open hand above an object it would come down on (``held``) and stops it,
        lowered around one, with its palm just over the top."""
        self.resting_on: int | None = None
        """The object around (or beside, under the palm) which the open hand is as low as it
        goes this tick, the input asking it lower (the guard's palm stop, or the reach's
        floor), or ``None``."""
        self.resting_centred = False
        """Whether the hand is then centred on that object along the slot (``CENTRED_M``)."""
        self.resting_offset = 0.0
        """The hand's offset then (m, world x) from that object's middle."""
        self._reach_below = reach_below
        self._slot = scene.spec.gripper_open
        self._floor = floor
        self._envelopes = scene.goals.envelopes
        self._half_widths = tuple(o.grasp_width / 2 for o in scene.spec.objects)
        self.objects_moved(scene.goals.positions)
        self._last_ee_z = math.inf  # the TCP's height at the last tick (``_note_resting``)
        # what the compiled steering keeps between ticks
        self.consts = self._constants()
        """``steer_core.steer``'s fixed numbers, or ``None``: the reference steers."""
        self.state = np.array((*self.guard.state(), self._last_ee_z))  # (``steer_core.STATE``)
        self.synced = True  # whether ``state`` holds the guard's state
        self._out = np.zeros(6)
        self._fallen_seen: tuple[int, ...] | None = None
        self._fallen = np.zeros(0, dtype=np.int64)  # the fallen objects' indices

    def objects_moved(self, grasp_points: np.ndarray) -> None:
        """The objects stand where their grasp points ``(n, 3)`` are now."""
        self.cylinders = self._object_cylinders(grasp_points)
        self.footprints = tuple(
            (*c, w) for c, w in zip(self.cylinders, self._half_widths, strict=True)
        )
        """Each object's cylinder with its half-width across the slot
        (``app.teleop.guarded_descent``)."""
        self.rows = rows(self.footprints)

    def _object_cylinders(self, grasp_points: np.ndarray) -> tuple[Cylinder, ...]:
        """Each object as ``(x, y, radius, top)`` where it stands now (``app.teleop.lift_out``)."""
        envelopes = self._envelopes
        if envelopes is None:
            return ()
        return tuple(
            (g[0], g[1], env[0], g[2] + env[1])
            for g, env in zip(grasp_points.tolist(), envelopes.tolist(), strict=True)
        )

    def _constants(self) -> np.ndarray | None:
        """The numbers ``steer_core.steer`` steers by (the guard's hand, the reach's floor),
        or ``None`` when the lift-out rule's would differ from the guard's."""
        guard = self.guard
        same = (guard.reach_below, guard.slot, guard.clearance) == (
            self._reach_below,
            self._slot,
            CLEARANCE_M,
        )
        if not same:  # pragma: no cover - one hand for both (``descent_guard``)
            return None
        return pack_consts(
            reach_below=guard.reach_below,
            slot=guard.slot,
            clearance=guard.clearance,
            palm_above=guard.palm_above,
            palm_half=guard.palm_half,
            parts=guard.parts,
            parts_lo=min((lo for lo, _, _ in guard.parts), default=math.inf),
            low=guard.low,
            floor=self._floor,
        )

    def closed(self) -> None:
        """The gripper is closed this tick: the hand steers to the user's target and rests on
        nothing; the guard lets go."""
        self.resting_on, self.resting_centred = None, False
        self.guard.release()
        self.synced = False

    def steer(
        self,
        ee: np.ndarray,
        target: np.ndarray,
        taking: int,
        fallen: tuple[int, ...],
        now: float,
    ) -> np.ndarray:
        """Where ``U`` steers the open hand this tick (the module's docstring): the TCP ``ee``,
        the user's ``target`` (returned itself when not steered), the object the robot takes
        the hand to (``taking``, ``-1``: none), the fallen objects, the time ``now``. In one
        call of ``steer_core.steer`` (the guard's state mirrored into it, and back when it
        changes), or by :meth:`reference` when ``consts`` is ``None``."""
        self.resting_on, self.resting_centred = None, False
        consts = self.consts
        if consts is None:
            return self.reference(ee, target, taking, fallen, now)
        state = self.state
        guard = self.guard
        if not self.synced:  # the guard was released, or is new: take its state
            state[:7] = guard.state()
            self.synced = True
        if fallen is not self._fallen_seen:
            self._fallen_seen = fallen
            self._fallen = np.array(fallen, dtype=np.int64)
        out = self._out
        flags = steer(ee, target, self.rows, taking, self._fallen, state, out, consts, now)
        if flags & CHANGED:
            guard.set_state(state.tolist())
        if flags & RESTING:
            _, _, _, resting, centred, offset = out.tolist()
            self.resting_on = int(resting)
            self.resting_centred = centred > 0.0
            self.resting_offset = offset
        return out[:3].copy() if flags & STEERED else target

    def reference(
        self,
        ee: np.ndarray,
        target: np.ndarray,
        taking: int,
        fallen: tuple[int, ...],
        now: float,
    ) -> np.ndarray:
        """:meth:`steer` in Python: the reference its compiled call is tested equal to."""
        guard = self.guard
        skip = (taking, *fallen)  # a dropped object still stands: guarded
        x, t = ee.tolist(), target.tolist()
        if guard.held is not None:  # a hold is kept until the guard lets go (its docstring)
            hold = guard.steer(x, t, self.footprints, now=now, skip=skip)
            if hold is not None:
                return np.array(hold)
        out = lift_out(
            x, t, self.cylinders, reach_below=self._reach_below, slot=self._slot, skip=skip
        )
        if out is not None:
            return np.array(out)
        hold = guard.steer(x, t, self.footprints, now=now, skip=skip)
        if hold is not None:
            return np.array(hold)
        rest = guard.rest(x, t, self.footprints, skip=skip)
        self._note_resting(x, t[2], rest, fallen)
        return target if rest is None else np.array(rest[0])

    def _note_resting(
        self,
        ee: list[float],
        target_z: float,
        rest: tuple[tuple[float, float, float], int] | None,
        fallen: tuple[int, ...],
    ) -> None:
        """``resting_on``: the object the open hand is around once it is as low as it goes --
        come down to ``rest_z``, the palm's stop the input asks below, or, with the input
        (at height ``target_z``) pushed to the reach's floor, there or no longer coming down
        (the robot may be carrying the hand to that object: its policy sets the height then);
        ``resting_centred``: centred on it along the slot (``CENTRED_M``)."""
        last, self._last_ee_z = self._last_ee_z, ee[2]
        rest_z = None if rest is None else rest[0][2]
        if rest_z is not None:
            if ee[2] > rest_z + 0.005:
                return  # still coming down to the palm's stop
        else:
            if target_z > self._floor + 1e-6:
                return  # the input does not ask it lower than it goes
            if ee[2] > target_z + 0.005 and abs(ee[2] - last) >= 2e-4:
                return  # still coming down
        guard, footprints = self.guard, self.footprints
        k = guard.under_palm(ee, footprints, skip=fallen, left=guard.palm_left)
        if k is None and rest is not None:
            k = rest[1]  # a part of the hand above the palm stopped beside a tall object
        if k is not None:
            self.resting_on = k
            self.resting_offset = ee[0] - footprints[k][0]
            self.resting_centred = (
                abs(self.resting_offset) <= CENTRED_M
                and guard.around(ee, footprints, skip=fallen) == k
            )

    def offset(self, ee: np.ndarray, fallen: Sequence[int]) -> float:
        """The open hand's offset along x from the middle of the object it is down around
        (its palm over it, the TCP below its top), if more than ``CENTRED_M``, else 0."""
        x = ee.tolist()
        k = self.guard.under_palm(x, self.footprints, skip=fallen)
        if k is None:
            return 0.0
        ox, _, _, top, _ = self.footprints[k]
        off = x[0] - ox
        return off if x[2] < top and abs(off) > CENTRED_M else 0.0


def rows(footprints: tuple[Footprint, ...]) -> np.ndarray:
    """The objects' footprints as an ``(n, 5)`` float array (``steer_core.steer``)."""
    return np.array(footprints, dtype=np.float64).reshape(-1, 5)


def descent_guard(scene: Scene, reach_below_m: float) -> DescentGuard:
    """The trial's ``DescentGuard`` for ``scene``'s hand (its fingertips ``reach_below_m`` under
    the TCP): its palm, the lowest layer above the fingers, and the parts above the palm (not
    the link before the last joint: its box, far off the TCP's axis, turns with it and reaches
    12-16 cm around it, where the link is not)."""
    palm = min(scene.hand[1:], key=lambda layer: layer.lo, default=None)
    upper = tuple(layer for layer in scene.hand[1:] if layer is not palm)
    above = min((layer.lo for layer in upper), default=0.0)
    return DescentGuard(
        reach_below=reach_below_m,
        slot=scene.spec.gripper_open,
        palm_above=palm.lo if palm is not None else math.inf,
        palm_half=_half_extent(palm),
        parts=tuple((layer.lo, *_half_extent(layer)) for layer in upper if not layer.turns),
        low=scene.reach.lo[2] + above,  # the arm above the palm, the hand at the reach's floor
    )


def _half_extent(layer: HandLayer | None) -> tuple[float, float]:
    """How far ``layer`` reaches to each side of the TCP along world x and y (its box about
    its centre; the TCP's x and y are the world's for the top-down hand)."""
    if layer is None:
        return (0.0, 0.0)
    return (abs(layer.center[0]) + layer.half[0], abs(layer.center[1]) + layer.half[1])

"""Policy blending: ``command = (1 - alpha) U + alpha P`` behind one object per control tick.

Per tick :meth:`PolicyBlender.step` takes the robot configuration ``Q`` and the user's next
configuration ``U`` (and optionally the user's input ``x`` in the predictor's space), and runs
predict (``P(G | xi)``, ``G*``) -> confidence -> policy (``P``) -> agreement -> arbitration
(``alpha``) -> blend, returning a :class:`BlendRecord` for logging. Alongside, it estimates the
user's rationality toward each goal from their recent inputs (``RationalityEstimator``), which
it logs and which a :class:`StatefulArbitration` may use with the agreement.
:meth:`PolicyBlender.step_joint` is the same tick for a caller that works out ``U``, ``P`` and
the command together (a compiled step: the trial's), and :meth:`PolicyBlender.step_compiled`
for one that works out the prediction, confidence and arbitration of stock components in the
same call (``app.blending.assess_core``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from operator import mul, sub
from typing import Any

import numpy as np

from . import assess_core
from .adaptive import StatefulArbitration, TickSignals
from .arbitration import Arbitration
from .confidence import Confidence
from .errors import BlendingError, InvalidInputError
from .goals import GoalSet
from .policy import Policy
from .prediction.base import GoalPrediction, Predictor
from .prediction.rationality import RationalityEstimator

__all__ = ["BlendRecord", "PolicyBlender", "blend"]

_F64 = np.dtype(np.float64)
_ORACLE, _MEMORY = float(assess_core.ORACLE), float(assess_core.MEMORY)

MAX_ABS_INPUT = 1e100
"""Per-tick inputs (Q, U, x) must be finite and below this in magnitude: no configuration or
position is anywhere near it, and the bound keeps squared distances from overflowing."""


def blend(u: np.ndarray, p: np.ndarray, alpha: float) -> np.ndarray:
    """``(1 - alpha) U + alpha P`` (a new array)."""
    if not 0.0 <= alpha <= 1.0:
        raise InvalidInputError(f"alpha: must be in [0, 1], got {alpha!r}")
    out = np.multiply(u, 1.0 - alpha)
    out += alpha * np.asarray(p)
    return out


class BlendRecord:
    """One tick, for the robot and for logging (read its fields, never write them).

    command: ``(1 - alpha) U + alpha P``; P: the policy's next configuration; alpha;
    confidence; distance: ``d`` from ``x`` to the predicted goal (predictor space);
    probabilities: ``P(G | xi)`` (a copy); predicted: index of G*; agreement: cosine of
    ``P - Q`` and ``U - Q`` (the robot's policy against the user's input direction, Fig. 15:
    near -1 when the user fights the robot, the "aggressive and wrong" signal; 0 when either
    velocity is zero); rationality: the user's estimated rationality toward G* (1/m);
    motion_agreement: cosine of the user's actual motion (the latest centimetre of their input)
    and the robot's heading (from the robot to G*, predictor space), 0 before they have moved:
    Fig. 15's "dot product between the robot's policy and the user's motion", which, unlike
    ``agreement``, stays positive when an assisting robot merely runs ahead of the user.

    ``agreement`` is worked out when first read, from ``Q`` and ``U`` (``qu``: lists or float
    arrays), unless given: the study's tick does not read it (a :class:`StatefulArbitration` does, and gets it).
    """

    __slots__ = (
        "P",
        "_agreement",
        "_qu",
        "alpha",
        "command",
        "confidence",
        "distance",
        "motion_agreement",
        "predicted",
        "probabilities",
        "rationality",
    )

    def __init__(
        self,
        command: np.ndarray,
        P: np.ndarray,
        alpha: float,
        confidence: float,
        distance: float,
        probabilities: np.ndarray,
        predicted: int,
        agreement: float | None = None,
        rationality: float = math.nan,
        motion_agreement: float = 0.0,
        *,
        qu: tuple[list[float] | np.ndarray, list[float] | np.ndarray] | None = None,
    ) -> None:
        if agreement is None and qu is None:
            raise InvalidInputError("BlendRecord: give agreement, or Q and U (qu) to work it out")
        self.command = command
        self.P = P
        self.alpha = alpha
        self.confidence = confidence
        self.distance = distance
        self.probabilities = probabilities
        self.predicted = predicted
        self.rationality = rationality
        self.motion_agreement = motion_agreement
        self._agreement = agreement
        self._qu = qu

    @property
    def agreement(self) -> float:
        """Cosine of ``P - Q`` and ``U - Q`` (0 when either is zero), clipped to [-1, 1]."""
        if self._agreement is None:
            qs, us = (v.tolist() if type(v) is np.ndarray else v for v in self._qu)  # type: ignore[union-attr]
            self._agreement = _agreement(np.asarray(self.P, dtype=np.float64).tolist(), qs, us)
        return self._agreement

    def __repr__(self) -> str:
        return (
            f"BlendRecord(alpha={self.alpha!r}, confidence={self.confidence!r},"
            f" predicted={self.predicted!r}, agreement={self.agreement!r},"
            f" command={self.command!r}, P={self.P!r})"
        )


class PolicyBlender:
    """Prediction, confidence, arbitration and policy joined per tick.

    Args:
        goals: the goal set.
        predictor: a goal predictor over the goals in ``space``.
        confidence: ``(prediction, distance) -> [0, 1]``.
        arbitration: ``c -> alpha``.
        policy: ``step(Q, target) -> P``; its ``target_space`` picks goal configurations,
            positions, or (``"goal"``) the goal's index into the goal set the blender hands the
            policy's ``set_goals`` whenever the goals change (grasp frames).
        feature: ``U -> x``, maps the user's configuration into the predictor's space (e.g.
            forward kinematics); ``None`` means ``x = U``.
        space: the predictor's space, ``"workspace"`` or ``"configuration"``; default
            ``"workspace"`` when ``feature`` is given, else ``"configuration"``.
        rationality: the user's rationality estimator (a default one when ``None``).
    """

    def __init__(
        self,
        *,
        goals: GoalSet,
        predictor: Predictor,
        confidence: Confidence,
        arbitration: Arbitration | Callable[[float], float],
        policy: Policy,
        feature: Callable[[np.ndarray], Any] | None = None,
        space: str | None = None,
        rationality: RationalityEstimator | None = None,
    ) -> None:
        if not isinstance(goals, GoalSet):
            raise InvalidInputError(f"goals: expected a GoalSet, got {type(goals).__name__}")
        if not isinstance(predictor, Predictor):
            raise InvalidInputError(
                f"predictor: needs n_goals, reset(start) and update(x), got {predictor!r}"
            )
        for name, obj in (("confidence", confidence), ("arbitration", arbitration)):
            if not callable(obj):
                raise InvalidInputError(f"{name}: expected a callable, got {obj!r}")
        if not isinstance(policy, Policy):
            raise InvalidInputError(
                f"policy: needs step(q, target) and target_space, got {policy!r}"
            )
        if feature is not None and not callable(feature):
            raise InvalidInputError(f"feature: expected a callable U -> x, got {feature!r}")
        if space is None:
            space = "workspace" if feature is not None else "configuration"
        if space not in ("workspace", "configuration"):
            raise InvalidInputError(f"space: must be 'workspace' or 'configuration', got {space!r}")
        self.space = space
        self.predictor = predictor
        self.confidence = confidence
        self.arbitration = arbitration
        self.policy = policy
        self.feature = feature
        self.rationality = rationality if rationality is not None else RationalityEstimator()
        self._update: Callable[[np.ndarray], GoalPrediction] = getattr(
            predictor, "_update", predictor.update
        )
        self._started = False
        self.dof: int | None = None
        self._q_shape: tuple[int, ...] = ()  # (dof,) once known
        self._arbitration_seen: object = None
        self._stateful = False
        self._numbers_seen: tuple[object, object, object] = (None, None, None)
        self._numbers: np.ndarray | None = None
        self._kind = -1.0  # the prediction kind of _numbers, as a float
        self._no_vector = np.empty(0)
        self._pred_points_seen: object = None
        self._pred_points = self._no_vector
        self._install_goals(goals)

    def _install_goals(self, goals: GoalSet) -> None:
        points = goals.points(self.space)
        if self.policy.target_space == "configuration" and goals.configurations is None:
            raise InvalidInputError(
                f"goals: {type(self.policy).__name__} steers toward goal configurations; give "
                "the GoalSet configurations (or use a workspace policy)"
            )
        set_goals = None
        if self.policy.target_space == "goal":  # the policy reads the goals' grasp frames
            set_goals = getattr(self.policy, "set_goals", None)
            if set_goals is None:
                raise InvalidInputError(
                    f"policy: {type(self.policy).__name__} steers toward goals by index"
                    " (target_space 'goal') but has no set_goals(goals)"
                )
            targets: Any = list(range(len(goals)))
        else:
            targets = goals.points(self.policy.target_space)
        if self.predictor.n_goals != len(goals):
            raise InvalidInputError(
                f"predictor: predicts over {self.predictor.n_goals} goals, the goal set has "
                f"{len(goals)}"
            )
        pred_points = getattr(self.predictor, "points", None)
        if pred_points is not None and pred_points.shape[1] != points.shape[1]:
            raise InvalidInputError(
                f"predictor: works in {pred_points.shape[1]}-D, the goals' {self.space} points "
                f"are {points.shape[1]}-D"
            )
        dof = goals.configurations.shape[1] if goals.configurations is not None else None
        if self.dof is not None and dof is not None and dof != self.dof:
            raise InvalidInputError(f"goals: configurations are {dof}-D, the robot is {self.dof}-D")
        if set_goals is not None:
            set_goals(goals)
        self.goals = goals
        self._points = points
        self._kernel_points = np.array(points, dtype=np.float64)  # writable, contiguous
        self._point_lists = points.tolist()
        self._targets = targets
        self.xdim = points.shape[1]
        if dof is not None:
            self.dof = dof
            self._q_shape = (dof,)
        self._x_shape = (self.xdim,)

    def set_goals(self, goals: GoalSet, *, predictor: Predictor | None = None) -> None:
        """Change the goals at run time (number and place). Without ``predictor`` the current
        predictor takes the new points (memory-based prediction keeps its trajectory)."""
        if not isinstance(goals, GoalSet):
            raise InvalidInputError(f"goals: expected a GoalSet, got {type(goals).__name__}")
        if predictor is None:
            set_points = getattr(self.predictor, "set_points", None)
            if set_points is None:
                raise InvalidInputError(
                    "predictor: cannot take new goals (no set_points); pass predictor="
                )
            set_points(goals.points(self.space))
        else:
            if not isinstance(predictor, Predictor):
                raise InvalidInputError(f"predictor: not a predictor: {predictor!r}")
            self.predictor = predictor
            self._update = getattr(predictor, "_update", predictor.update)
            self._started = False
        self._install_goals(goals)

    def reset(self, start_x: Any) -> None:
        """Start a trajectory at ``S``, the user's first input in the predictor's space."""
        s = np.asarray(start_x, dtype=np.float64)
        if s.shape != (self.xdim,):
            raise InvalidInputError(f"start_x: expected shape ({self.xdim},), got {s.shape}")
        if not np.isfinite(s).all():
            raise InvalidInputError(f"start_x: contains NaN or infinite values: {s!r}")
        self.predictor.reset(s)
        self.rationality.reset(s)
        if isinstance(self.arbitration, StatefulArbitration):
            self.arbitration.reset()
        self._started = True

    def _bad_input(self, *named: tuple[str, np.ndarray]) -> BlendingError:
        """The error for the first of these inputs that is not finite or is absurdly large."""
        for name, arr in named:
            if not np.isfinite(arr).all():
                return InvalidInputError(f"{name}: contains NaN or infinite values: {arr!r}")
            if (np.abs(arr) >= MAX_ABS_INPUT).any():
                return InvalidInputError(
                    f"{name}: values of magnitude >= {MAX_ABS_INPUT:g} are not a configuration "
                    f"or position: {arr!r}"
                )
        return InvalidInputError("inputs: not finite")  # pragma: no cover

    def _checked_x(self, Q: np.ndarray, x: np.ndarray) -> list[float]:
        """``x`` as a list, once the blender is started and ``Q`` and ``x`` have their shapes
        and ``x`` is finite and below ``MAX_ABS_INPUT`` (as in :meth:`step`)."""
        if not self._started:
            raise InvalidInputError("reset(start_x) must be called before step(Q, U)")
        if Q.shape != self._q_shape or x.shape != self._x_shape:
            raise InvalidInputError(
                f"Q, x: expected shapes {self._q_shape} and {self._x_shape}, got {Q.shape} and"
                f" {x.shape}"
            )
        xs = x.tolist()
        if not sum(map(abs, xs)) < MAX_ABS_INPUT:  # NaN, inf, absurd values
            raise self._bad_input(("x", x))
        return xs

    def step(self, Q: Any, U: Any, *, x: Any = None, robot_x: Any = None) -> BlendRecord:
        """One tick; ``x`` defaults to ``feature(U)`` (or ``U``); ``robot_x`` is where the robot
        is in the predictor's space (e.g. its end effector), ``x`` when not given."""
        if not self._started:
            raise InvalidInputError("reset(start_x) must be called before step(Q, U)")
        q = Q if type(Q) is np.ndarray and Q.dtype == _F64 else np.asarray(Q, dtype=np.float64)
        u = U if type(U) is np.ndarray and U.dtype == _F64 else np.asarray(U, dtype=np.float64)
        dof = self._dof(q, u)
        if x is None:
            x = u if self.feature is None else np.asarray(self.feature(u), dtype=np.float64)
        elif type(x) is not np.ndarray or x.dtype != _F64:
            x = np.asarray(x, dtype=np.float64)
        if x.shape != self._x_shape:
            raise InvalidInputError(
                f"x: expected shape ({self.xdim},) in {self.space} space, got {x.shape}"
            )
        # one cheap check: NaN compares False, so this rejects NaN, inf and absurd magnitudes
        # (a sum of magnitudes below MAX_ABS_INPUT bounds every entry; only when it is not does
        # the exact per-entry test run, which raises for NaN, inf or magnitudes >= the bound)
        if (
            not sum(map(abs, (qs := q.tolist()) + (us := u.tolist()) + (xs := x.tolist())))
            < MAX_ABS_INPUT
            and not np.abs(np.concatenate((q, u, x))).max() < MAX_ABS_INPUT
        ):
            raise self._bad_input(("Q", q), ("U", u), ("x", x))

        pred, b, motion, distance, c = self.assess(x, xs, robot_x)
        i = pred.index
        p = self.policy.step(q, self._targets[i])
        ps = _checked_policy(p, dof)
        arb = self.arbitration
        agreement = None  # worked out when read (BlendRecord.agreement), unless needed now
        if self.stateful:
            agreement = _agreement(ps, qs, us)
            alpha = float(arb.update(TickSignals(c, agreement, motion, i, b)))
        else:
            alpha = float(arb(c))
        if not 0.0 <= alpha <= 1.0:
            raise BlendingError(f"arbitration: returned alpha = {alpha!r}, outside [0, 1]")
        cmd = u * (1.0 - alpha)
        if alpha != 0.0:  # alpha = 0 (no assistance yet): the command is U itself
            cmd += alpha * p
        probs = pred.probabilities.copy()
        return BlendRecord(
            cmd, p, alpha, c, distance, probs, i, agreement, float(b[i]), motion, qu=(qs, us)
        )

    def step_joint(
        self,
        Q: np.ndarray,
        *,
        x: np.ndarray,
        robot_x: Any = None,
        act: Callable[[Any, float], tuple[np.ndarray, np.ndarray, np.ndarray, bool]],
    ) -> BlendRecord:
        """:meth:`step` for a caller that works out ``U``, ``P`` and the command together (the
        trial's compiled step): ``act(target, alpha) -> (U, P, command, finite)``, ``target``
        the policy's target for G*, ``command = (1 - alpha) U + alpha P`` and ``finite``
        whether ``Q``, ``U`` and ``P`` are finite and below ``MAX_ABS_INPUT`` (checked in the
        same pass). The same prediction, confidence, arbitration and record as :meth:`step`
        (``Q`` and ``x`` float arrays; ``x`` is checked before the prediction advances, ``Q``
        with ``U`` and ``P`` after). Not for a stateful arbitration, which reads the agreement
        of ``U`` and ``P`` before ``alpha``: use :meth:`step` there."""
        xs = self._checked_x(Q, x)
        if self.stateful:
            raise InvalidInputError("step_joint: a stateful arbitration needs step(Q, U)")
        pred, b, motion, distance, c = self.assess(x, xs, robot_x)
        i = pred.index
        alpha = float(self.arbitration(c))
        if not 0.0 <= alpha <= 1.0:
            raise BlendingError(f"arbitration: returned alpha = {alpha!r}, outside [0, 1]")
        u, p, cmd, finite = act(self._targets[i], alpha)
        if not finite or not (u.shape == p.shape == self._q_shape):
            raise BlendingError(
                f"Q, U or P: not {self.dof} finite values each (or of magnitude >="
                f" {MAX_ABS_INPUT:g}): Q {Q!r}, U {u!r}, P {p!r}"
            )
        probs = pred.probabilities.copy()
        return BlendRecord(
            cmd, p, alpha, c, distance, probs, i, None, float(b[i]), motion, qu=(Q, u)
        )

    def step_compiled(
        self,
        Q: np.ndarray,
        *,
        x: np.ndarray,
        robot_x: np.ndarray,
        act: Callable[..., tuple[Any, ...]],
    ) -> BlendRecord:
        """:meth:`step` for a caller that works out the whole tick in one compiled call --
        prediction, distance, confidence, arbitration and motion agreement
        (:func:`~app.blending.assess_core.assess`), then ``U``, ``P`` and the blend -- with
        stock components (:meth:`compiled_numbers` not ``None``; else :meth:`step_joint`).

        The blender checks ``x`` (and ``Q`` with ``U`` and ``P`` as ``act`` reports them, as
        :meth:`step_joint`), advances the rationality estimate (its direction is the motion
        agreement's), and calls ``act(*inputs)``, ``inputs`` ``assess``'s arguments up to
        ``b``; ``act`` returns ``(U, P, command, P(G | xi), G*, conf, d, motion agreement,
        alpha, C(xi_{S->U}), finite)``. The same record as :meth:`step` (``Q``, ``x`` and
        ``robot_x`` float arrays)."""
        self._checked_x(Q, x)
        nums = self.compiled_numbers()
        if nums is None or self.stateful:
            raise InvalidInputError(
                "step_compiled: needs the stock prediction, confidence and arbitration"
                " (compiled_numbers()); use step_joint or step"
            )
        pred: Any = self.predictor
        kind = self._kind
        k, c_su, b_pred, prev, vec, vec2 = 0, 0.0, 0.0, x, self._no_vector, self._no_vector
        pred_points = self._kernel_points
        if kind == _ORACLE:
            k = pred.goal
        else:
            if kind == _MEMORY:
                c_su, prev, vec2, b_pred = pred.kernel_inputs(x)
                vec = pred.log_prior
            if pred.points is not self._points:
                pred_points = self._predictor_points(pred.points)
        b = self.rationality.update(x, self._points)
        d = self.rationality.direction
        u, p, cmd, probs, i, c, distance, motion, alpha, c_su, finite = act(
            x,
            robot_x,
            self._no_vector if d is None else d,
            self._kernel_points,
            pred_points,
            vec,
            vec2,
            prev,
            nums,
            k,
            c_su,
            b_pred,
        )
        if i < 0:  # pragma: no cover - finite inputs give finite logits
            raise InvalidInputError("logits: no goal has a finite log-probability")
        if kind == _MEMORY:
            pred.note_update(x, c_su)
        if not finite or not (u.shape == p.shape == self._q_shape):
            raise BlendingError(
                f"Q, U or P: not {self.dof} finite values each (or of magnitude >="
                f" {MAX_ABS_INPUT:g}): Q {Q!r}, U {u!r}, P {p!r}"
            )
        return BlendRecord(
            cmd, p, alpha, c, distance, probs, i, None, float(b[i]), motion, qu=(Q, u)
        )

    def compiled_numbers(self) -> np.ndarray | None:
        """:func:`app.blending.assess_core.numbers` for this blender's prediction, confidence and
        arbitration (worked out again when one of them is swapped): ``None`` unless all three
        are stock kinds that :meth:`step_compiled` computes."""
        seen = self._numbers_seen
        if (
            self.predictor is not seen[0]
            or self.confidence is not seen[1]
            or self.arbitration is not seen[2]
        ):
            key = self._numbers_seen = (self.predictor, self.confidence, self.arbitration)
            nums = self._numbers = assess_core.numbers(*key) if self.xdim == 3 else None
            self._kind = -1.0 if nums is None else float(nums[0])
        return self._numbers

    def _predictor_points(self, points: np.ndarray) -> np.ndarray:
        """A writable contiguous copy of the predictor's own goal points (kept while they are
        the same array)."""
        if points is not self._pred_points_seen:
            self._pred_points_seen = points
            self._pred_points = np.array(points, dtype=np.float64)
        return self._pred_points

    @property
    def stateful(self) -> bool:
        """Whether the arbitration keeps a state (it then reads the agreement of ``U`` and
        ``P``: :meth:`step_joint` is not for it)."""
        arb = self.arbitration
        if arb is not self._arbitration_seen:  # asked once per object
            self._arbitration_seen = arb
            self._stateful = isinstance(arb, StatefulArbitration)
        return self._stateful

    def assess(
        self, x: np.ndarray, xs: list[float], robot_x: Any
    ) -> tuple[GoalPrediction, np.ndarray, float, float, float]:
        """What a tick reads from the user's input alone, before ``P`` and ``alpha``:
        ``(prediction, rationality per goal, motion agreement, distance d to G*, confidence)``
        for ``x`` (a checked float array, ``xs`` its list) with the robot at ``robot_x``
        (``None``: at ``x``). Advances the predictor and the rationality estimate: once per
        tick (``step`` calls it; a compiled fast path calls it instead of ``step``)."""
        pred = self._update(x)
        i = pred.index
        b = self.rationality.update(x, self._points)
        motion = self._motion_agreement(x if robot_x is None else robot_x, i)
        distance = math.dist(xs, self._point_lists[i])
        c = float(self.confidence(pred, distance))
        if not 0.0 <= c <= 1.0:
            raise BlendingError(f"confidence: returned {c!r}, outside [0, 1]")
        return pred, b, motion, distance, c

    def _dof(self, q: np.ndarray, u: np.ndarray) -> int:
        """The robot's degrees of freedom (from the first ``Q`` seen), ``Q`` and ``U`` checked
        against it."""
        dof = self.dof
        if dof is not None and q.shape == u.shape == self._q_shape:
            return dof
        if dof is None:
            if q.ndim != 1:
                raise InvalidInputError(f"Q: expected a 1-D configuration, got shape {q.shape}")
            dof = self.dof = q.shape[0]
            self._q_shape = (dof,)
        if q.shape != (dof,):
            raise InvalidInputError(f"Q: expected shape ({dof},), got {q.shape}")
        if u.shape != (dof,):
            raise InvalidInputError(f"U: expected shape ({dof},), got {u.shape}")
        return dof

    def _motion_agreement(self, robot_x: Any, i: int) -> float:
        d = self.rationality.direction
        if d is None:
            return 0.0
        if type(robot_x) is not np.ndarray or robot_x.dtype != _F64:
            robot_x = np.asarray(robot_x, dtype=np.float64)
        heading = self._points[i] - robot_x
        n = math.sqrt(float(heading.dot(heading)))
        return float(d.dot(heading)) / n if n > 0.0 else 0.0


def _checked_policy(p: Any, dof: int) -> list[float]:
    """The policy's ``P`` as a list, after checking that it has ``dof`` finite values."""
    pa = p if type(p) is np.ndarray and p.dtype == _F64 else np.asarray(p, dtype=np.float64)
    if pa.ndim != 1 or pa.shape[0] != dof:
        raise BlendingError(f"policy: returned P of {pa.size} values, the robot has {dof}")
    ps = pa.tolist()
    # a sum of finite values may still overflow: only then the exact test runs
    if not math.isfinite(sum(ps)) and not np.isfinite(pa).all():
        raise BlendingError(f"policy: returned a non-finite P {p!r}")
    return ps


def _agreement(ps: list[float], qs: list[float], us: list[float]) -> float:
    """Cosine of ``P - Q`` and ``U - Q`` (0 when either is zero), clipped to [-1, 1]."""
    # the velocities P - Q and U - Q in scalars (seven numbers: cheaper than arrays)
    pv = list(map(sub, ps, qs))
    uv = list(map(sub, us, qs))
    pp = sum(map(mul, pv, pv))
    nn = math.sqrt(pp * sum(map(mul, uv, uv)))
    agreement = sum(map(mul, pv, uv)) / nn if nn > 0.0 else 0.0
    return 1.0 if agreement > 1.0 else (-1.0 if agreement < -1.0 else agreement)

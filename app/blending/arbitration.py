"""Arbitration ``alpha = a(conf)``: how much the robot's prediction P weighs in the command.

Section 3.2: ``alpha in [0, 1]`` and non-decreasing in confidence. Every arbitration here is
checked at construction on a dense grid of confidences (plus its breakpoints); a function that
leaves [0, 1] or decreases raises :class:`InvalidArbitrationError`.

Theorem 1: blending never yields an inescapable local minimum unless the arbitration is
adversarial: for every non-zero user velocity ``u``, ``p = -k u`` with ``alpha = 1/(k + 1)``
(``k >= 0``), or ``p = 0`` and ``alpha = 1``. :func:`is_adversarial` tests this on samples.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ._checks import as_finite_array, in_interval
from .errors import InvalidArbitrationError, InvalidInputError

__all__ = [
    "Aggressive",
    "Arbitration",
    "FunctionArbitration",
    "Linear",
    "NoAssistance",
    "PiecewiseLinear",
    "Timid",
    "check_arbitration",
    "is_adversarial",
]

_GRID = np.linspace(0.0, 1.0, 1001)


def check_arbitration(
    fn: Callable[[float], float], *, name: str = "arbitration", extra: Sequence[float] = ()
) -> None:
    """Raise :class:`InvalidArbitrationError` unless ``fn`` maps [0, 1] into [0, 1] and never
    decreases, checked on 1001 evenly spaced confidences plus ``extra`` (e.g. breakpoints,
    approached from both sides)."""
    pts = _GRID.tolist()
    for b in extra:
        pts.extend(float(x) for x in (b - 1e-9, b, b + 1e-9) if 0.0 <= x <= 1.0)
    cs = np.unique(np.array(pts))
    try:
        vals = np.array([float(fn(c)) for c in cs.tolist()])
    except (TypeError, ValueError) as exc:
        raise InvalidArbitrationError(f"{name}: could not evaluate on [0, 1]: {exc}") from None
    bad = ~np.isfinite(vals) | (vals < 0.0) | (vals > 1.0)
    if bad.any():
        i = int(np.argmax(bad))
        raise InvalidArbitrationError(
            f"{name}: alpha must stay in [0, 1], got alpha({cs[i]:g}) = {vals[i]!r}"
        )
    dec = np.diff(vals) < -1e-12
    if dec.any():
        i = int(np.argmax(dec))
        raise InvalidArbitrationError(
            f"{name}: alpha must not decrease with confidence, got alpha({cs[i]:g}) = "
            f"{vals[i]:g} > alpha({cs[i + 1]:g}) = {vals[i + 1]:g}"
        )


_CHECKED: dict[tuple[Any, ...], None] = {}
"""The arbitrations :func:`check_once` has passed, by class, parameters and extra points."""
_CHECKED_MAX = 256  # kinds and parameters kept at most (emptied when full)


def check_once(
    fn: Callable[[float], float], *, name: str = "arbitration", extra: Sequence[float] = ()
) -> None:
    """:func:`check_arbitration`, done once per process for an arbitration whose own class
    declares ``_params()`` -- its ``alpha(c)`` a function of those numbers alone (the stock
    kinds): a trial builds the same few arbitrations again and again, and each check (about
    0.25 ms, twice per built arbitration) was a sixth of setting up a trial. Any other
    callable, a subclass that does not declare ``_params`` of its own included, is checked
    every time."""
    params = type(fn).__dict__.get("_params")
    if params is None:
        check_arbitration(fn, name=name, extra=extra)
        return
    key = (type(fn), params(fn), tuple(extra))
    if key in _CHECKED:
        return
    check_arbitration(fn, name=name, extra=extra)
    if len(_CHECKED) >= _CHECKED_MAX:
        _CHECKED.clear()
    _CHECKED[key] = None


class Arbitration(ABC):
    """Base: ``__call__(c) -> alpha``; subclasses set up, then call ``self._validate()``."""

    _breakpoints: tuple[float, ...] = ()

    @abstractmethod
    def __call__(self, c: float) -> float:
        """``alpha(c)`` in [0, 1], non-decreasing in the confidence ``c``."""

    def _validate(self) -> None:
        check_once(self, name=type(self).__name__, extra=self._breakpoints)


class NoAssistance(Arbitration):
    """``alpha = 0``: the user alone (unassisted and training runs)."""

    def __init__(self) -> None:
        self._validate()

    def __call__(self, c: float) -> float:
        return 0.0

    def _params(self) -> tuple[float, ...]:
        return ()

    def __repr__(self) -> str:
        return "NoAssistance()"


class Timid(Arbitration):
    """``alpha = alpha_max * min(1, c / saturation)``: rises with confidence, then plateaus at
    ``alpha_max < 1``, never taking full charge (Fig. 7)."""

    def __init__(self, alpha_max: float, saturation: float = 1.0) -> None:
        self.alpha_max = in_interval(
            alpha_max, name="alpha_max", lo=0, hi=1, lo_open=True, hi_open=True
        )
        self.saturation = in_interval(saturation, name="saturation", lo=0, hi=1, lo_open=True)
        self._slope = self.alpha_max / self.saturation
        self._breakpoints = (self.saturation,)
        self._validate()

    def __call__(self, c: float) -> float:
        if c >= self.saturation:
            return self.alpha_max
        return self._slope * c if c > 0.0 else 0.0

    def _params(self) -> tuple[float, ...]:
        return (self.alpha_max, self.saturation)

    def __repr__(self) -> str:
        return f"Timid(alpha_max={self.alpha_max}, saturation={self.saturation})"


class Aggressive(Arbitration):
    """``alpha = 0`` below ``threshold``, ``alpha_high`` from it on: eagerly takes charge as
    soon as confidence passes the threshold (Fig. 7)."""

    def __init__(self, threshold: float, alpha_high: float = 1.0) -> None:
        self.threshold = in_interval(threshold, name="threshold", lo=0, hi=1)
        self.alpha_high = in_interval(alpha_high, name="alpha_high", lo=0, hi=1, lo_open=True)
        self._breakpoints = (self.threshold,)
        self._validate()

    def __call__(self, c: float) -> float:
        return self.alpha_high if c >= self.threshold else 0.0

    def _params(self) -> tuple[float, ...]:
        return (self.threshold, self.alpha_high)

    def __repr__(self) -> str:
        return f"Aggressive(threshold={self.threshold}, alpha_high={self.alpha_high})"


class Linear(Arbitration):
    """``alpha = alpha_min + (alpha_max - alpha_min) c`` on ``c in [0, 1]`` (clamped)."""

    def __init__(self, alpha_min: float = 0.0, alpha_max: float = 1.0) -> None:
        self.alpha_min = in_interval(alpha_min, name="alpha_min", lo=0, hi=1)
        self.alpha_max = in_interval(alpha_max, name="alpha_max", lo=0, hi=1)
        if self.alpha_max < self.alpha_min:
            raise InvalidArbitrationError(
                f"alpha_max: must be >= alpha_min ({self.alpha_min}) so alpha does not "
                f"decrease with confidence, got {self.alpha_max}"
            )
        self._validate()

    def __call__(self, c: float) -> float:
        c = 0.0 if c < 0.0 else (1.0 if c > 1.0 else c)
        return self.alpha_min + (self.alpha_max - self.alpha_min) * c

    def _params(self) -> tuple[float, ...]:
        return (self.alpha_min, self.alpha_max)

    def __repr__(self) -> str:
        return f"Linear(alpha_min={self.alpha_min}, alpha_max={self.alpha_max})"


class PiecewiseLinear(Arbitration):
    """Linear interpolation through ``points = [(c_0, alpha_0), ...]`` (``c`` strictly
    increasing in [0, 1]); constant beyond the first and last points."""

    def __init__(self, points: Any) -> None:
        pts = as_finite_array(points, name="points", ndim=2, dim=2)
        if pts.shape[0] < 1:
            raise InvalidInputError("points: give at least one (confidence, alpha) pair")
        c, a = pts[:, 0], pts[:, 1]
        if (c < 0).any() or (c > 1).any():
            raise InvalidInputError(f"points: confidences must be in [0, 1], got {c.tolist()}")
        if (np.diff(c) <= 0).any():
            raise InvalidInputError(
                f"points: confidences must be strictly increasing, got {c.tolist()}"
            )
        if (a < 0).any() or (a > 1).any():
            raise InvalidArbitrationError(f"points: alpha must stay in [0, 1], got {a.tolist()}")
        if (np.diff(a) < 0).any():
            raise InvalidArbitrationError(
                f"points: alpha must not decrease with confidence, got {a.tolist()}"
            )
        self._c = [float(v) for v in c]
        self._a = [float(v) for v in a]
        self.points = tuple(zip(self._c, self._a, strict=True))
        self._breakpoints = tuple(self._c)
        self._validate()

    def __call__(self, c: float) -> float:
        cs, al = self._c, self._a
        if c <= cs[0]:
            return al[0]
        if c >= cs[-1]:
            return al[-1]
        i = 1
        while cs[i] < c:
            i += 1
        t = (c - cs[i - 1]) / (cs[i] - cs[i - 1])
        return al[i - 1] + t * (al[i] - al[i - 1])

    def _params(self) -> tuple[float, ...]:
        return (*self._c, *self._a)

    def __repr__(self) -> str:
        return f"PiecewiseLinear(points={list(self.points)})"


class FunctionArbitration(Arbitration):
    """Wrap any callable ``c -> alpha``; rejected at construction unless it maps [0, 1] into
    [0, 1] without decreasing (checked on a grid plus ``breakpoints``)."""

    def __init__(self, fn: Callable[[float], float], *, breakpoints: Sequence[float] = ()) -> None:
        if not callable(fn):
            raise InvalidInputError(f"fn: expected a callable c -> alpha, got {fn!r}")
        self.fn = fn
        self._breakpoints = tuple(float(b) for b in breakpoints)
        self._validate()

    def __call__(self, c: float) -> float:
        return float(self.fn(c))

    def __repr__(self) -> str:
        return f"FunctionArbitration({self.fn!r})"


def is_adversarial(u: Any, p: Any, alpha: Any, *, atol: float = 1e-9) -> bool:
    """Theorem 1: is this arbitration the adversarial case, on these samples?

    Evaluate the policy and the arbitration at ``m`` sample user inputs from one state ``Q``
    and pass, per sample ``i``: the user velocity ``u[i] = U_i - Q``, the prediction velocity
    ``p[i] = P_i - Q`` and ``alpha[i]``. The blend is a local minimum for sample ``i`` when
    ``(1 - alpha) u + alpha p = 0``, which for ``u != 0`` holds exactly when ``p = -k u`` with
    ``alpha = 1/(k + 1)`` (``k >= 0``) or ``p = 0`` and ``alpha = 1``.

    Returns ``True`` when every sample with a non-zero ``u`` is such a minimum (no sampled input
    escapes: the adversarial case), ``False`` as soon as one sampled input moves the robot
    (which, by the theorem, shows the state is escapable). Samples can only refute
    adversarialness, so sample the inputs broadly (several directions and magnitudes).

    Raises InvalidInputError on mismatched shapes, non-finite values, alpha outside [0, 1], or
    when no sample has a non-zero ``u``.
    """
    u_arr = as_finite_array(u, name="u", ndim=2)
    p_arr = as_finite_array(p, name="p", ndim=2)
    a_arr = as_finite_array(alpha, name="alpha", ndim=1)
    if p_arr.shape != u_arr.shape:
        raise InvalidInputError(f"p: expected shape {u_arr.shape} like u, got {p_arr.shape}")
    if a_arr.shape != (u_arr.shape[0],):
        raise InvalidInputError(f"alpha: expected shape ({u_arr.shape[0]},), got {a_arr.shape}")
    if (a_arr < 0).any() or (a_arr > 1).any():
        raise InvalidInputError(f"alpha: values must be in [0, 1], got {a_arr.tolist()}")
    atol = float(atol)
    if not atol >= 0:
        raise InvalidInputError(f"atol: must be >= 0, got {atol!r}")
    moving = np.linalg.norm(u_arr, axis=1) > atol
    if not moving.any():
        raise InvalidInputError("u: every sample is zero; sample non-zero user inputs")
    step = (1.0 - a_arr[moving, None]) * u_arr[moving] + a_arr[moving, None] * p_arr[moving]
    return bool((np.linalg.norm(step, axis=1) <= atol).all())

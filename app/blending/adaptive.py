"""Stateful arbitration: alpha from the confidence *and* from how the user has been moving.

The paper's section 6 asks for arbitration that adapts to the robot's confidence in itself and
in the user, and notes that the dot product between the robot's policy and the user's motion
(Fig. 15) betrays "aggressive and wrong" early. A :class:`StatefulArbitration` keeps a state
``s``; each tick :meth:`~StatefulArbitration.update` takes the tick's :class:`TickSignals`,
advances ``s`` and returns ``alpha_t``. With the state frozen, ``__call__(c)`` is an ordinary
arbitration: it is checked like the others (in [0, 1], non-decreasing in ``c``) and,
depending on ``u`` only through the state, it is never Theorem 1's adversarial case.

Both kinds here start from the aggressive curve ``a(c) = alpha_high [c >= threshold]`` and
scale it by a gain ``g in [0, 1]``, never below ``floor`` unless the curve itself is:

    alpha = min(a(c), max(floor, g a(c)))

which is non-decreasing in ``c`` for every ``g``, never exceeds ``a(c)``, and equals it at
``g = 1``.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import NamedTuple

import numpy as np

from ._checks import in_interval, positive
from .arbitration import Arbitration
from .errors import InvalidInputError

__all__ = ["StatefulArbitration", "TickSignals", "UserConfidence", "Yielding"]


class TickSignals(NamedTuple):
    """What a stateful arbitration sees each tick.

    confidence: ``c``; agreement: cosine of ``P - Q`` and ``U - Q`` (0 when either is zero);
    motion_agreement: cosine of the user's actual motion and the robot's heading to G* (Fig.
    15; see ``BlendRecord``); predicted: index of G*; rationality: the user's estimated
    rationality toward each goal (1/m, ``RationalityEstimator``).
    """

    confidence: float
    agreement: float
    motion_agreement: float
    predicted: int
    rationality: np.ndarray


class StatefulArbitration(Arbitration):
    """Arbitration with a state: ``reset()`` at the start of a trial, ``update(signals)`` once
    per tick (returns that tick's alpha), ``__call__(c)`` = alpha with the state frozen."""

    def __init__(self, *, threshold: float, alpha_high: float, floor: float) -> None:
        self.threshold = in_interval(threshold, name="threshold", lo=0, hi=1)
        self.alpha_high = in_interval(alpha_high, name="alpha_high", lo=0, hi=1, lo_open=True)
        self.floor = in_interval(floor, name="floor", lo=0, hi=1)
        self._breakpoints = (self.threshold,)
        self.gain = 1.0

    @abstractmethod
    def reset(self) -> None:
        """Back to the initial state (full trust: ``gain = 1``)."""

    @abstractmethod
    def update(self, signals: TickSignals) -> float:
        """Advance the state by one tick; return ``alpha`` for this tick."""

    def aggressive(self, c: float) -> float:
        """The curve both kinds start from, ``a(c)``."""
        return self.alpha_high if c >= self.threshold else 0.0

    def __call__(self, c: float) -> float:
        a = self.aggressive(c)
        return min(a, max(self.floor, self.gain * a))


class Yielding(StatefulArbitration):
    """Aggressive while the user agrees with the robot; yields quickly when fought.

    Each tick of length ``dt = 1 / rate_hz``, with the agreement ``r_t`` (``signal = "motion"``,
    the default: the cosine of the user's actual motion and the robot's heading, Fig. 15;
    ``"policy"``: the cosine of ``P - Q`` and ``U - Q``, which also turns negative when a
    helping robot runs ahead of the user's input):

        tau_t = tau_{t-1} + dt  if r_t < agree_below,  else 0      (time spent fighting)
        g_t   = g_{t-1} exp(-dt / fall_s)                  if tau_t >= window_s   (yield)
        g_t   = 1 - (1 - g_{t-1}) exp(-dt / recover_s)     if r_t >= agree_below  (recover)
        g_t   = g_{t-1}                                    otherwise (disagreeing, briefly)
        alpha_t = min(a(c_t), max(floor, g_t a(c_t)))

    So a disagreement shorter than ``window_s`` (a correction, sensor noise) changes nothing;
    a sustained one brings alpha from ``alpha_high`` to ``floor`` within a few ``fall_s``; and
    trust returns over a few ``recover_s`` (choose ``recover_s >> fall_s``) once the user's
    motion agrees with the robot's again. Right predictions keep aggressive's help; a wrong one
    costs the user about ``window_s + 2 fall_s`` of fighting instead of the whole trial.
    """

    def __init__(
        self,
        *,
        threshold: float,
        alpha_high: float = 1.0,
        agree_below: float = 0.0,
        window_s: float = 0.3,
        floor: float = 0.1,
        fall_s: float = 0.2,
        recover_s: float = 2.0,
        signal: str = "motion",
        rate_hz: float,
    ) -> None:
        super().__init__(threshold=threshold, alpha_high=alpha_high, floor=floor)
        if signal not in ("motion", "policy"):
            raise InvalidInputError(f"signal: 'motion' or 'policy', got {signal!r}")
        self.signal = signal
        self.agree_below = in_interval(agree_below, name="agree_below", lo=-1, hi=1)
        self.window_s = positive(window_s, name="window_s", allow_zero=True)
        self.fall_s = positive(fall_s, name="fall_s")
        self.recover_s = positive(recover_s, name="recover_s")
        self.rate_hz = positive(rate_hz, name="rate_hz")
        self.dt = 1.0 / self.rate_hz
        self._fall = math.exp(-self.dt / self.fall_s)
        self._recover = math.exp(-self.dt / self.recover_s)
        self.reset()
        self._validate()

    def reset(self) -> None:
        self.gain = 1.0
        self.fighting_s = 0.0

    def update(self, signals: TickSignals) -> float:
        r = signals.motion_agreement if self.signal == "motion" else signals.agreement
        if r < self.agree_below:
            self.fighting_s += self.dt
            if self.fighting_s >= self.window_s - 1e-12:
                self.gain *= self._fall
        else:
            self.fighting_s = 0.0
            self.gain = 1.0 - (1.0 - self.gain) * self._recover
        return self(signals.confidence)

    def __repr__(self) -> str:
        return (
            f"Yielding(threshold={self.threshold}, alpha_high={self.alpha_high}, "
            f"agree_below={self.agree_below}, window_s={self.window_s}, floor={self.floor}, "
            f"fall_s={self.fall_s}, recover_s={self.recover_s}, signal={self.signal!r}, "
            f"rate_hz={self.rate_hz})"
        )


class UserConfidence(StatefulArbitration):
    """Aggressive, scaled by the robot's confidence in the *user*: is the user rational with
    respect to the goal the robot predicts?

    With ``b_G`` the user's estimated rationality toward goal ``G`` from their recent motion
    (eq. 9's ``b``, estimated online, see ``RationalityEstimator``), each tick

        g_t = min(1, b_{G*} / max(beta_ref, max_G b_G)),
        alpha_t = min(a(c_t), max(floor, g_t a(c_t))).

    Rationale: the confidence ``c`` says how sure the robot is of *its* prediction; ``g`` says
    how well that prediction explains what the user is doing. When the user moves efficiently
    toward G* (``b_{G*}`` high and the largest), the robot takes the aggressive curve's full
    authority. When another goal explains the motion much better (``b_G >> b_{G*}``: the user
    is rational, but about a goal the robot does not predict, the "aggressive and wrong" case)
    or no goal explains it (``b_{G*} < beta_ref``: the model of a noisily-optimal user reaching
    for G* does not fit now), the robot's authority shrinks toward ``floor`` -- as in the
    confidence-aware human models of Fisac et al. (2018), which widen their predictions when
    the rationality estimate falls. Unlike ``yielding`` it needs no fighting: motion that goes
    elsewhere is enough, and it recovers as soon as the estimate does.
    """

    def __init__(
        self,
        *,
        threshold: float,
        alpha_high: float = 1.0,
        beta_ref: float = 20.0,
        floor: float = 0.1,
    ) -> None:
        super().__init__(threshold=threshold, alpha_high=alpha_high, floor=floor)
        self.beta_ref = positive(beta_ref, name="beta_ref")
        self.reset()
        self._validate()

    def reset(self) -> None:
        self.gain = 1.0

    def update(self, signals: TickSignals) -> float:
        b = signals.rationality
        if b.size:
            top = max(self.beta_ref, float(b.max()))
            self.gain = min(1.0, float(b[signals.predicted]) / top)
        return self(signals.confidence)

    def __repr__(self) -> str:
        return (
            f"UserConfidence(threshold={self.threshold}, alpha_high={self.alpha_high}, "
            f"beta_ref={self.beta_ref}, floor={self.floor})"
        )

"""Human movement primitives: minimum-jerk reaches, Fitts' law timing, hand noise.

- Minimum jerk (Flash & Hogan 1985): ``r(phi) = r0 + (g - r0) s(phi)``,
  ``s(phi) = 10 phi^3 - 15 phi^4 + 6 phi^5`` for ``phi in [0, 1]`` (zero velocity and
  acceleration at both ends; peak speed ``1.875 D / T`` at ``phi = 1/2``).
- Fitts' law: movement time ``T = a + b log2(1 + D / W)``.
- Hand noise: an Ornstein-Uhlenbeck process ``n_{k+1} = e^{-dt/tau} n_k + sd sqrt(1 -
  e^{-2 dt/tau}) xi``, ``xi ~ N(0, I)``: smooth, stationary standard deviation ``sd``.
"""

from __future__ import annotations

import math

import numpy as np


def minimum_jerk(phi: float) -> float:
    """Normalised minimum-jerk position ``s(phi)``, clamped to ``[0, 1]`` outside the movement."""
    if phi <= 0.0:
        return 0.0
    if phi >= 1.0:
        return 1.0
    return phi * phi * phi * (10.0 + phi * (-15.0 + 6.0 * phi))


def fitts_time(distance: float, *, a: float, b: float, width: float) -> float:
    """``T = a + b log2(1 + D / W)`` seconds for a reach of ``distance`` metres."""
    return a + b * math.log2(1.0 + max(distance, 0.0) / width)


class HandNoise:
    """Ornstein-Uhlenbeck noise on the hand target, seeded by the caller's generator."""

    def __init__(self, *, sd: float, tau: float, rng: np.random.Generator, dim: int = 3) -> None:
        self.sd = sd
        self.tau = tau
        self.rng = rng
        self.value = np.zeros(dim)

    def step(self, dt: float, *, scale: float = 1.0) -> np.ndarray:
        """Advance by ``dt`` seconds with the stationary sd multiplied by ``scale``."""
        decay = math.exp(-dt / self.tau)
        kick = self.sd * scale * math.sqrt(1.0 - decay * decay)
        self.value = decay * self.value + kick * self.rng.standard_normal(self.value.shape[0])
        return self.value

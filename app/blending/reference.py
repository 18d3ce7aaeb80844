"""Exact reference for memory-based prediction: soft-maximum value iteration on a 2-D grid.

Ziebart et al. (2009). The user model is the MaxEnt distribution over grid paths,
``P(xi | G) ∝ exp(-b C(xi))``, with ``C`` the path length (8-connected moves of length ``h``
or ``h sqrt 2``). Eq. 4 of the paper is then exact:

``P(xi_{S->U} | G) = exp(-b C(xi_{S->U})) Z_G(U) / Z_G(S)``,
``Z_G(s) = sum over paths s -> G (ending at their first arrival at G) of exp(-b C(path))``,

and ``V_G = -log Z_G`` is the soft value: ``V_G(s) = -log sum_a exp(-b c(s, a) - V_G(s'))``,
``V_G(G) = 0``. Because ``Z_G`` is linear in itself (``Z = e_G + W Z`` off the goal), this
module solves that linear system exactly instead of iterating. The sum over paths converges
when the total move weight ``4 e^{-b h} + 4 e^{-b h sqrt 2}`` is below 1.

This is far too slow for a 7-DoF arm (the paper's point) and exists to test the eq. 9
approximation against; it is not used per tick.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ._checks import positive
from .errors import InvalidInputError

__all__ = ["grid_log_partition", "grid_posterior"]

_MOVES = [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0)]


def grid_log_partition(
    shape: tuple[int, int], goal: tuple[int, int], *, rationality: float, cell: float = 1.0
) -> np.ndarray:
    """``log Z_G(s) = -V_G(s)`` for every cell ``s`` of a ``shape`` grid (indices ``(i, j)``)."""
    h, w = (int(shape[0]), int(shape[1]))
    if h < 1 or w < 1:
        raise InvalidInputError(f"shape: must be positive, got {shape}")
    gi, gj = goal
    if not (0 <= gi < h and 0 <= gj < w):
        raise InvalidInputError(f"goal: {goal} is outside the {shape} grid")
    b = positive(rationality, name="rationality") * positive(cell, name="cell")
    if 4 * math.exp(-b) + 4 * math.exp(-b * math.sqrt(2)) >= 1.0:
        raise InvalidInputError(
            f"rationality: b * cell = {b:g} is too small for the path sum to converge "
            "(need 4 e^-b + 4 e^-b sqrt2 < 1, i.e. b * cell > 1.76)"
        )
    n = h * w
    a = np.eye(n)
    g = gi * w + gj
    for i in range(h):
        for j in range(w):
            s = i * w + j
            if s == g:
                continue
            for di, dj in _MOVES:
                ii, jj = i + di, j + dj
                if 0 <= ii < h and 0 <= jj < w:
                    a[s, ii * w + jj] -= math.exp(-b * math.hypot(di, dj))
    rhs = np.zeros(n)
    rhs[g] = 1.0
    z = np.linalg.solve(a, rhs)
    return np.log(z).reshape(h, w)


def grid_posterior(
    shape: tuple[int, int],
    goals: Sequence[tuple[int, int]],
    trajectory: Sequence[tuple[int, int]],
    *,
    rationality: float,
    cell: float = 1.0,
    prior: Sequence[float] | None = None,
) -> np.ndarray:
    """Exact ``P(G | xi_{S->U})`` for a grid trajectory (``S = trajectory[0]``,
    ``U = trajectory[-1]``): ``∝ Z_G(U) / Z_G(S) P(G)`` (the prefix cost is shared, cancels)."""
    if len(trajectory) < 1:
        raise InvalidInputError("trajectory: give at least the start cell")
    if len(goals) < 1:
        raise InvalidInputError("goals: the goal set is empty")
    s, u = trajectory[0], trajectory[-1]
    logp = np.empty(len(goals))
    for k, goal in enumerate(goals):
        log_z = grid_log_partition(shape, goal, rationality=rationality, cell=cell)
        logp[k] = log_z[u] - log_z[s]
    if prior is not None:
        pr = np.asarray(prior, dtype=np.float64)
        if pr.shape != (len(goals),) or (pr < 0).any() or pr.sum() <= 0:
            raise InvalidInputError(f"prior: expected {len(goals)} weights >= 0, got {prior}")
        with np.errstate(divide="ignore"):
            logp = logp + np.log(pr / pr.sum())
    logp -= logp.max()
    p = np.exp(logp)
    return p / p.sum()

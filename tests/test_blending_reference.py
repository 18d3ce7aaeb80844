"""Eq. 9 against the exact posterior: soft-maximum value iteration on a 2-D grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.blending import AmnesicPredictor, InvalidInputError, MemoryPredictor
from app.blending.reference import _MOVES, grid_log_partition, grid_posterior

B = 3.0  # rationality per cell length


def test_log_partition_hand_computed_corridor() -> None:
    # 1x3 corridor, goal at the end, w = e^-b: Z1 = w + w Z0, Z0 = w Z1
    # -> Z1 = w / (1 - w^2), Z0 = w^2 / (1 - w^2)
    w = math.exp(-B)
    lz = grid_log_partition((1, 3), (0, 2), rationality=B)
    np.testing.assert_allclose(
        lz[0], [math.log(w * w / (1 - w * w)), math.log(w / (1 - w * w)), 0.0]
    )


def test_soft_bellman_equation_holds() -> None:
    """V(s) = -log sum_a exp(-b c(s, a) - V(s')) off the goal, V(G) = 0."""
    shape, goal = (7, 9), (2, 5)
    v = -grid_log_partition(shape, goal, rationality=B)
    assert v[goal] == pytest.approx(0.0, abs=1e-12)
    for i in range(shape[0]):
        for j in range(shape[1]):
            if (i, j) == goal:
                continue
            terms = [
                -B * math.hypot(di, dj) - v[i + di, j + dj]
                for di, dj in _MOVES
                if 0 <= i + di < shape[0] and 0 <= j + dj < shape[1]
            ]
            assert v[i, j] == pytest.approx(-np.logaddexp.reduce(terms), abs=1e-9)
    # the soft value is a little below the shortest path length (many near-optimal paths)
    assert 0 < B * 3 - v[2, 2] < 1.0


def test_reference_rejects_divergent_rationality() -> None:
    with pytest.raises(InvalidInputError, match="too small"):
        grid_log_partition((5, 5), (1, 1), rationality=1.0)
    with pytest.raises(InvalidInputError, match="outside"):
        grid_log_partition((5, 5), (5, 1), rationality=B)


def _eq9(goals, traj, b=B):
    pred = MemoryPredictor(np.array(goals, float), rationality=b)
    pred.reset(np.array(traj[0], float))
    for x in traj[1:]:
        out = pred.update(np.array(x, float))
    return out


# Hand-made scenarios on a 15 x 15 grid: (goals, trajectory, intended goal index)
SCENARIOS = [
    # Fig. 3: heading for the farther goal while nearer the other -> the farther
    ([(5, 5), (2, 14)], [(2, 0), (2, 1), (2, 2), (2, 3), (3, 4)], 1),
    # straight toward one of three goals
    ([(0, 14), (14, 14), (7, 0)], [(7, 7), (6, 8), (5, 9), (4, 10)], 0),
    ([(0, 14), (14, 14), (7, 0)], [(7, 7), (8, 8), (9, 9)], 1),
    ([(0, 14), (14, 14), (7, 0)], [(7, 7), (7, 6), (7, 5)], 2),
    # noisy approach: a zig-zag that still makes progress toward goal 1
    ([(0, 0), (0, 14)], [(10, 7), (9, 8), (9, 9), (8, 8), (7, 9), (6, 10)], 1),
    # backtracking: first toward goal 0, then clearly turning to goal 1
    ([(0, 7), (14, 7)], [(7, 7), (6, 7), (6, 7), (7, 7), (8, 7), (9, 7), (10, 7)], 1),
]


@pytest.mark.parametrize(("goals", "traj", "intended"), SCENARIOS)
def test_eq9_argmax_matches_exact_posterior(goals, traj, intended) -> None:
    exact = grid_posterior((15, 15), goals, traj, rationality=B)
    approx = _eq9(goals, traj)
    assert exact.argmax() == intended
    assert approx.index == intended


def test_fig3_scenario_amnesic_disagrees_with_exact() -> None:
    goals, traj, intended = SCENARIOS[0]
    amn = AmnesicPredictor(np.array(goals, float), temperature=0.5)
    assert amn.update(np.array(traj[-1], float)).index != intended


def test_eq9_agrees_with_exact_on_random_decisive_scenarios() -> None:
    """Random noisy walks toward random goals; wherever the exact posterior is decisive (top
    two differ by >= 0.1), eq. 9 picks the same goal. Many scenarios must qualify."""
    rng = np.random.default_rng(7)
    shape = (13, 13)
    logz_cache: dict[tuple[int, int], np.ndarray] = {}
    checked = 0
    for _ in range(80):
        n = int(rng.integers(2, 5))
        cells = rng.choice(shape[0] * shape[1], size=n + 1, replace=False)
        pts = [(int(c // shape[1]), int(c % shape[1])) for c in cells]
        goals, s = pts[:n], pts[n]
        k = int(rng.integers(n))
        cur = np.array(s)
        traj = [s]
        for _ in range(int(rng.integers(2, 7))):
            d = np.sign(np.array(goals[k]) - cur)
            if rng.random() < 0.3:
                d = rng.integers(-1, 2, size=2)
            nxt = np.clip(cur + d, 0, shape[0] - 1)
            if tuple(int(v) for v in nxt) in goals:
                break
            cur = nxt
            traj.append((int(cur[0]), int(cur[1])))
        if len(traj) < 2:
            continue
        logp = []
        for g in goals:
            if g not in logz_cache:
                logz_cache[g] = grid_log_partition(shape, g, rationality=B)
            logp.append(logz_cache[g][traj[-1]] - logz_cache[g][traj[0]])
        exact = np.exp(np.array(logp) - max(logp))
        exact /= exact.sum()
        # the helper and the cached computation agree
        if checked == 0:
            np.testing.assert_allclose(grid_posterior(shape, goals, traj, rationality=B), exact)
        top2 = np.sort(exact)[-2:]
        if top2[1] - top2[0] < 0.1:
            continue
        checked += 1
        assert _eq9(goals, traj).index == int(exact.argmax()), (goals, traj, exact)
    assert checked >= 40

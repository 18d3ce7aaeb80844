"""Small fast helpers for 3-vectors on the simulated user's per-tick path (called ~15 times a
tick, where ``numpy.linalg.norm`` and ``ReachRegion.clamp``'s validation would dominate)."""

from __future__ import annotations

import math

import numpy as np


def norm(v: np.ndarray) -> float:
    """``|v|`` (Euclidean)."""
    return math.sqrt(float(v @ v))


def clamp_box(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``min(max(x, lo), hi)`` per axis, for a finite ``x`` the caller computed itself."""
    return np.minimum(np.maximum(x, lo), hi)

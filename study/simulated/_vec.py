"""Small fast helpers for 3-vectors on the simulated user's per-tick path (called ~15 times a
tick, where ``numpy.linalg.norm`` and ``ReachRegion.clamp``'s validation would dominate; finite
checks: ``app.teleop.reach.finite3``)."""

from __future__ import annotations

import math

import numpy as np


def norm(v: np.ndarray) -> float:
    """``|v|`` (Euclidean): the same dot product as ``v @ v`` and ``numpy.linalg.norm``, bit for
    bit, at half the call's cost."""
    return math.sqrt(v.dot(v))


def clamp_box(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``min(max(x, lo), hi)`` per axis, for a finite ``x`` the caller computed itself."""
    return np.minimum(np.maximum(x, lo), hi)

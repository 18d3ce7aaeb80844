"""What the control tick's compiled kernels share: numba's ``njit`` as used here, and LAPACK.

``jit``: ``numba.njit`` with the machine code cached (``app/__pycache__/numba-<hash>``), so
only the first process after a change compiles (``app.warm_up``); IEEE arithmetic as written
(no ``fastmath``: no reordering, no fused multiply-adds), so a kernel gives the very numbers
its Python gives. The GIL is kept: a kernel runs for microseconds, and a thread that lets it go
may wait a switch interval (5 ms) to have it back while another thread computes.
numba keys a kernel's cache on its own source file only, and a kernel calls (inlines) other
modules' kernels: edited ``solve_spd`` or ``assess_core``, the fused step's cache would keep the
old code and tests pass on it. So the cache lives in a folder named by a hash of every kernel
source (this module and each ``*_core.py``, :func:`cache_dir`): any edit compiles all afresh.

``solve_spd(a, b)``: ``b <- A^-1 b`` for a symmetric positive definite ``A`` (its upper
triangle read) by LAPACK's ``dposv``, the very routine ``scipy.linalg.lapack.dposv`` calls
(found by symbol through scipy's ``cython_lapack``), so a kernel solves as the reference does.

The damped least squares both steps of a tick take, ``dq = z + J^T (J J^T + l^2 I)^-1 (t - J
z)`` (``z`` only when ``pull``): ``dls`` with numpy's products (``np.dot``: scipy's BLAS, numpy's
numbers) and ``dposv``, as the Python references; ``dls_loops`` the same formula in plain loops
and a Cholesky factorisation of its own (no library calls: about a fifth of the time between
MuJoCo's steps, which evict the libraries' code), equal to ``dls`` to a few ulps, not bit for
bit (``tests/test_fused_control.py``).
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import shutil
from pathlib import Path

import llvmlite.binding as llvm
import numba
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

__all__ = ["cache_dir", "dls", "dls_loops", "jit", "solve_spd"]


def cache_dir(root: Path = Path(__file__).parent) -> Path:
    """``root/__pycache__/numba-<hash>``: the hash of every kernel source under ``root``
    (``compiled.py`` and each ``*_core.py``, by path and content)."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        if path.name == "compiled.py" or path.name.endswith("_core.py"):
            digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return root / "__pycache__" / f"numba-{digest.hexdigest()[:16]}"


def _use_cache_dir(folder: Path) -> None:
    """numba's cache in ``folder`` from now on (read as each kernel is decorated); the
    folders of earlier sources go."""
    for old in folder.parent.glob("numba-*"):
        if old != folder:
            with contextlib.suppress(OSError):
                shutil.rmtree(old)
    numba.config.CACHE_DIR = str(folder)


_use_cache_dir(cache_dir())
jit = njit(cache=True)

llvm.add_symbol(
    "shared_control_dposv", get_cython_function_address("scipy.linalg.cython_lapack", "dposv")
)
_p = types.voidptr
_dposv = types.ExternalFunction("shared_control_dposv", types.void(_p, _p, _p, _p, _p, _p, _p, _p))


@jit
def solve_spd(a: np.ndarray, b: np.ndarray) -> int:
    """``b <- A^-1 b`` in place for ``A`` (n, n) symmetric positive definite, by ``dposv``
    (``uplo = 'U'``, ``A`` handed over column-major as f2py does); LAPACK's ``info`` (0: solved).
    ``A`` is left as it was."""
    n = a.shape[0]
    col = np.empty(n * n)  # column-major copy (dposv overwrites it with the factor)
    for i in range(n):
        for j in range(n):
            col[i + n * j] = a[i, j]
    ints = np.array([n, 1, n, n, 0], dtype=np.int32)  # n, nrhs, lda, ldb, info
    uplo = np.array([85], dtype=np.uint8)  # 'U'
    _dposv(
        uplo.ctypes,
        ints[0:].ctypes,
        ints[1:].ctypes,
        col.ctypes,
        ints[2:].ctypes,
        b.ctypes,
        ints[3:].ctypes,
        ints[4:].ctypes,
    )
    return int(ints[4])


@jit
def dls(
    jac: np.ndarray, twist: np.ndarray, z: np.ndarray, pull: bool, lam2: np.ndarray
) -> tuple[np.ndarray, int]:
    """``(dq, info)``: ``dq = z + J^T y``, ``(J J^T + l^2 I) y = twist - J z`` (``z`` only when
    ``pull``; ``twist`` overwritten) by numpy's products and ``dposv``; ``info`` LAPACK's."""
    if pull:
        twist -= np.dot(jac, z)
    a = np.dot(jac, jac.T)
    a += lam2
    info = solve_spd(a, twist)
    dq = np.dot(jac.T, twist)
    if pull:
        dq += z
    return dq, info


@jit
def dls_loops(
    jac: np.ndarray, twist: np.ndarray, z: np.ndarray, pull: bool, lam2: np.ndarray
) -> tuple[np.ndarray, int]:
    """:func:`dls` in plain loops: ``A = J J^T + l^2 I = L L^T`` (Cholesky), then two
    triangular solves; ``info`` ``k + 1`` when ``A``'s ``k``-th pivot is not positive."""
    m, n = jac.shape
    if pull:
        for i in range(m):
            s = 0.0
            for j in range(n):
                s += jac[i, j] * z[j]
            twist[i] -= s
    low, info = _cholesky_of_jjt(jac, lam2)
    if info != 0:
        return np.zeros(n), info
    y = _cholesky_solve(low, twist)
    dq = np.empty(n)
    for j in range(n):
        s = 0.0
        for i in range(m):
            s += jac[i, j] * y[i]
        dq[j] = s + z[j] if pull else s
    return dq, 0


@jit
def _cholesky_of_jjt(jac: np.ndarray, lam2: np.ndarray) -> tuple[np.ndarray, int]:
    """``L`` with ``L L^T = J J^T + l^2 I`` (lower triangle filled), and ``info`` as
    :func:`dls_loops` gives it."""
    m, n = jac.shape
    low = np.empty((m, m))
    for i in range(m):
        for j in range(i + 1):
            s = 0.0
            for k in range(n):
                s += jac[i, k] * jac[j, k]
            s += lam2[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            if i == j:
                if not s > 0.0:
                    return low, i + 1
                low[i, i] = math.sqrt(s)
            else:
                low[i, j] = s / low[j, j]
    return low, 0


@jit
def _cholesky_solve(low: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``y`` with ``L L^T y = b``: forward, then back substitution."""
    m = b.shape[0]
    y = np.empty(m)
    for i in range(m):  # L y' = b
        s = b[i]
        for k in range(i):
            s -= low[i, k] * y[k]
        y[i] = s / low[i, i]
    for i in range(m - 1, -1, -1):  # L^T y = y'
        s = y[i]
        for k in range(i + 1, m):
            s -= low[k, i] * y[k]
        y[i] = s / low[i, i]
    return y

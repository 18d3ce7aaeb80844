"""What the control tick's compiled kernels share: numba's ``njit`` as used here, and LAPACK.

``jit``: ``numba.njit`` with the machine code cached beside the source (``__pycache__``), so
only the first process after a change compiles (``app.warm_up``); IEEE arithmetic as written
(no ``fastmath``: no reordering, no fused multiply-adds), so a kernel gives the very numbers
its Python gives. The GIL is kept: a kernel runs for microseconds, and a thread that lets it go
may wait a switch interval (5 ms) to have it back while another thread computes.
numba keys a kernel's cache on its own source file only: after editing this module, delete the
caches (``find app -name '*.nb[ic]' -delete``) or a kernel keeps the old ``solve_spd``.

``solve_spd(a, b)``: ``b <- A^-1 b`` for a symmetric positive definite ``A`` (its upper
triangle read) by LAPACK's ``dposv``, the very routine ``scipy.linalg.lapack.dposv`` calls
(found by symbol through scipy's ``cython_lapack``), so a kernel solves as the reference does.
"""

from __future__ import annotations

import llvmlite.binding as llvm
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

__all__ = ["jit", "solve_spd"]

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

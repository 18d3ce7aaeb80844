"""Run in a worker process: what importing a module costs there (stdlib imports only, so that
unpickling this function imports nothing of the study's)."""

from __future__ import annotations

import importlib
import sys
import time


def cpu_to_import(module: str, *, already: str) -> tuple[float, bool]:
    """CPU seconds this process spends importing ``module``, and whether ``already`` was
    imported before."""
    was_there = already in sys.modules
    t0 = time.process_time()
    importlib.import_module(module)
    return time.process_time() - t0, was_there

"""Commands of ``python -m analysis``: report, anova, predict (one module each)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from functools import wraps

from analysis.errors import AnalysisError

USAGE_ERROR = 2


def fail(message: str) -> int:
    """Print ``error: message`` on stderr and return the usage-error exit code (2)."""
    print(f"error: {message}", file=sys.stderr)
    return USAGE_ERROR


def friendly(main: Callable[..., int]) -> Callable[..., int]:
    """Each command's one catch: the analysis' errors (:class:`AnalysisError`, the root of
    every error it raises on purpose) as one line and exit code 2. What the operating system
    refuses beyond them (a file gone between check and read, an output folder not writable,
    a full disk) gets one line too; anything else is a bug and keeps its traceback."""

    @wraps(main)
    def wrapper(args: object) -> int:
        try:
            return main(args)
        except AnalysisError as e:
            return fail(str(e))
        except FileNotFoundError as e:
            return fail(f"file not found: {e.filename}. Check the path.")
        except (OSError, UnicodeDecodeError) as e:
            return fail(f"cannot read input: {e}")

    return wrapper


def note(message: str) -> None:
    """A remark about the data (aggregation, dropped rows) on stderr."""
    print(f"note: {message}", file=sys.stderr)

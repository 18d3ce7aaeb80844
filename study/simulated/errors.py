"""Typed errors of the simulated-participant package.

Every message names what was wrong (a file, a key path, a value) and what to do about it.
"""

from __future__ import annotations

from study.errors import StudyError


class SimulationError(StudyError):
    """Base class of every error raised by ``study.simulated``."""


class PopulationError(SimulationError, ValueError):
    """A population file or table is invalid; the message names the key path and the fix."""


class ObservationError(SimulationError, ValueError):
    """An observation a simulated user cannot act on (non-finite position, unknown target)."""


class SimulationRunError(SimulationError, RuntimeError):
    """A simulated session could not be driven to its end through the session engine."""


class SchedulerUnreachableError(SimulationError, ConnectionError):
    """The Dask scheduler given with ``--scheduler`` did not answer; the message names the
    address and what to check."""

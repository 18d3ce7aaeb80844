"""The kernel's real-time class for the study server, and above it for the threads that keep time.

:func:`set_realtime` puts the calling thread, and so every server thread started from it later,
in the kernel's round-robin real-time class (``SCHED_RR``) at its lowest priority, 1; the threads
that keep time -- the control loops and the sample committer -- call :func:`enter_timekeeping`
as they start and run at a higher one. A server thread is then run the moment it can run, ahead
of every ordinary program, and a due control tick or sample commit ahead of the rest of the
server. Nice values only share the CPU out: with four software-WebGL tabs on the same 2 cores
(CPU 98-100 % busy), the control threads alone in the real-time class still stalled, waiting for
the interpreter lock held by an ordinary server thread the kernel had set aside for Chromium;
with the whole server in it the loops held 96-100 ticks in every 0.25-s window
(``benchmarks/README.md``, "The port's promise measured again"). The kernel keeps 5 % of every
second for ordinary threads whatever real-time ones do (``sched_rt_runtime_us``), and the server
sleeps most of the time (a control thread 98 % of each period). Needs the right to raise
priority (root, ``CAP_SYS_NICE`` or an ``RLIMIT_RTPRIO`` allowance); without it nothing changes
and :func:`set_realtime` says so.
"""

from __future__ import annotations

import logging
import os

from study.errors import StudyError

LOGGER = logging.getLogger("study.scheduling")
_timekeeping: int | None = None


class SchedulingError(StudyError, ValueError):
    """A real-time priority outside what the kernel's class takes: give 2..99."""


def set_realtime(control: int | None) -> bool:
    """Put the calling thread (and the threads it starts later) in ``SCHED_RR`` at priority 1,
    and time-keeping threads started later at ``control`` (2..99); ``None`` puts the calling
    thread back among ordinary threads and leaves time-keeping threads ordinary. Returns
    whether the kernel allowed it (when not, nothing changed)."""
    global _timekeeping
    if control is None:
        _timekeeping = None
        if hasattr(os, "sched_setscheduler"):
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        return True
    if not 2 <= control <= 99:
        raise SchedulingError(f"a control thread's real-time priority is 2..99, got {control}")
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(1))
    except (OSError, AttributeError):  # not permitted, or not Linux
        _timekeeping = None
        return False
    _timekeeping = control
    return True


def enter_timekeeping() -> None:
    """Called by a control loop's or the sample committer's thread as it starts: take the
    time-keeping priority if one is set (a refusal, e.g. a changed limit, is logged and the
    thread runs on)."""
    if _timekeeping is None:
        return
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(_timekeeping))
    except OSError as exc:
        LOGGER.warning("a time-keeping thread keeps the server's priority: %s", exc)

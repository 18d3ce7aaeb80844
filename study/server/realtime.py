"""Keep control loops on time in a process that also serves websockets.

The control loops, the sample writers and the websocket servers share one interpreter. Under
a reconnect storm, the loop's worst 0.25-s windows fell to 0-40 ticks a second, and the stalls
were not the connections' own work but the cyclic garbage collector: every connection leaves
short-lived cycles, collections follow, and a full one walked the ~170,000 objects the server
holds from start-up (arm models, viser, the protocol) for up to 0.9 s with the interpreter
lock held (``benchmarks/README.md``).

* :func:`freeze_heap` moves everything alive at start-up into the collector's permanent
  generation (``gc.freeze``), after one full collection: later collections walk only what
  was made since (sessions, trials, connections). :func:`thaw_heap` undoes it when the server
  stops (counted, so nested servers in one process -- tests -- are fine).
* :func:`set_priority` sets the scheduling priority (nice value) of the calling thread, which
  threads started from it later inherit (Linux keeps one per thread): ``serve`` calls it before
  the servers start, so the control loops, the sample writers and the websocket threads all run
  ahead of browsers and other work on the machine. A whole process, not just the control
  threads: a control thread waiting for the interpreter lock held by a thread the kernel has
  set aside behind other programs would wait for that program. Below 0 needs the right to
  raise priority (root, ``CAP_SYS_NICE`` or an ``RLIMIT_NICE`` allowance); without it nothing
  changes and ``None`` says so.
* :func:`set_realtime` puts the calling thread, and so every server thread started from it
  later, in the kernel's round-robin real-time class (``SCHED_RR``) at its lowest priority, 1,
  and the control threads started from then on (each calls :func:`enter_control` first) at a
  higher one: a thread of the server is run the moment it can run, ahead of every ordinary
  program, and a due control tick ahead of the rest of the server. Nice values only share the
  CPU out: with four software-WebGL tabs on the same 2 cores (CPU 98-100 % busy), the control
  threads alone in the real-time class still stalled, waiting for the interpreter lock held by
  an ordinary server thread the kernel had set aside for Chromium; with the whole server in it
  the loops held 92-100 ticks in every 0.25-s window (``benchmarks/README.md``, "The port's
  promise measured again"). The kernel keeps 5 % of every second for ordinary threads whatever
  real-time ones do (``sched_rt_runtime_us``), and the server sleeps most of the time (a
  control thread 98 % of each period). Needs the same right as raising priority; without it
  nothing changes and :func:`set_realtime` says so.
"""

from __future__ import annotations

import gc
import logging
import os
import sys
import threading

_frozen = 0
_lock = threading.Lock()
_control_rr: int | None = None
LOGGER = logging.getLogger("study.server.realtime")


def freeze_heap() -> None:
    """Collect once, then leave everything alive now out of later collections."""
    global _frozen
    with _lock:
        _frozen += 1
        gc.collect()
        gc.freeze()


def thaw_heap() -> None:
    """Undo one :func:`freeze_heap`; the last one gives the frozen objects back to the
    collector (whatever of them is garbage by now is collected in a later full collection)."""
    global _frozen
    with _lock:
        _frozen = max(0, _frozen - 1)
        if _frozen == 0:
            gc.unfreeze()


def set_priority(nice: int) -> int | None:
    """Set the calling thread's nice value (threads it starts later inherit it); returns the
    value now in effect, or ``None`` when the change was not allowed."""
    who = threading.get_native_id() if sys.platform.startswith("linux") else 0
    try:
        os.setpriority(os.PRIO_PROCESS, who, nice)
        return os.getpriority(os.PRIO_PROCESS, who)
    except (OSError, AttributeError):  # not permitted, or no such call on this platform
        return None


def set_realtime(control: int | None) -> bool:
    """Put the calling thread (and the threads it starts later) in ``SCHED_RR`` at priority 1,
    and control threads started later at ``control`` (2..99); ``None`` puts the calling thread
    back among ordinary threads and leaves control threads ordinary. Returns whether the
    kernel allowed it (when not, nothing changed)."""
    global _control_rr
    if control is None:
        _control_rr = None
        if hasattr(os, "sched_setscheduler"):
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        return True
    if not 2 <= control <= 99:
        raise ValueError(f"a control thread's real-time priority is 2..99, got {control}")
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(1))
    except (OSError, AttributeError):  # not permitted, or not Linux
        _control_rr = None
        return False
    _control_rr = control
    return True


def enter_control() -> None:
    """Called by a control thread as it starts: take the control threads' real-time priority
    if one is set (a refusal, e.g. a changed limit, is logged and the thread runs on)."""
    if _control_rr is None:
        return
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(_control_rr))
    except OSError as exc:
        LOGGER.warning("a control thread keeps the server's priority: %s", exc)

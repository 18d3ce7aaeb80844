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
* the kernel's real-time class for the whole server, and above it for the threads that keep
  time, is :mod:`study.scheduling` (``serve --realtime``).
"""

from __future__ import annotations

import gc
import os
import sys
import threading

_frozen = 0
_lock = threading.Lock()


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

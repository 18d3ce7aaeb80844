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
"""

from __future__ import annotations

import gc
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

"""Trials a dead process left ``running``, and how readers report them (nothing is written).

A trial row says ``running`` from its start until its process records how it ended. If that
process died (SIGKILL, power loss) and the session was never resumed, the row stays ``running``
for good. Readers (``Store.trials``, ``Store.trial``, ``Store.frame("trials")``, hence export
and analysis) report such an *orphaned* trial as resuming would record it
(``Transaction.interrupt_running_trials``): status and outcome ``interrupted``, not successful,
``ticks`` = samples that reached the file, ``duration_s`` = the last sample's ``t``. The file
is not changed: the store may still be open in a live session elsewhere.

A ``running`` trial is orphaned when no live process holds its participant's session lease
(``study.store.liveness.holder_is_live``): no lease row, a dead or recycled pid on this host, or on
another host a heartbeat older than ``stale_after_s``.
"""

from __future__ import annotations

import sqlite3
import time
from dataclasses import dataclass

from study.store import liveness

STALE_AFTER_S = 15.0
"""Heartbeat age after which another host's lease holder counts as dead (sessions beat every
2 s)."""

ORPHAN_NOTE = (
    "process ended during the trial (reported as interrupted; the store row still says running "
    "until the session is resumed)"
)


@dataclass(frozen=True, slots=True)
class Orphan:
    """What a reader reports for an orphaned trial (see module docstring)."""

    ticks: int
    duration_s: float | None


def orphaned_trials(
    conn: sqlite3.Connection, *, stale_after_s: float = STALE_AFTER_S
) -> dict[int, Orphan]:
    """``{trial_id: Orphan}`` for every ``running`` trial whose process is gone (read-only)."""
    rows = conn.execute(
        "SELECT t.trial_id, l.pid, l.host, l.process_start, l.heartbeat_at "
        "FROM trials t LEFT JOIN leases l USING (participant) WHERE t.status = 'running'"
    ).fetchall()
    now = time.time()
    orphans: dict[int, Orphan] = {}
    for trial_id, pid, host, started, heartbeat_at in rows:
        if pid is not None and liveness.holder_is_live(
            pid=pid,
            host=host,
            started=started,
            heartbeat_age_s=now - heartbeat_at,
            stale_after_s=stale_after_s,
        ):
            continue
        n, last_t = conn.execute(
            "SELECT count(*), max(t) FROM samples WHERE trial_id = ?", (trial_id,)
        ).fetchone()
        orphans[int(trial_id)] = Orphan(ticks=int(n), duration_s=last_t)
    return orphans

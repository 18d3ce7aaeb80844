"""Session leases: which process may write a participant's session (its holder's liveness is
``study.store.liveness``).

A lease row stores the holder's pid, host, process start time and a heartbeat; a process
that finds a live holder gets ``SessionLockedError``, one that finds a dead holder takes the
lease over and is told whose it was.
"""

from __future__ import annotations

import os
import time
import uuid
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

from study.store.errors import SessionLockedError
from study.store.liveness import HOST, holder_is_live, process_start
from study.store.orphans import STALE_AFTER_S
from study.store.records import Lease
from study.store.transaction import Transaction
from study.store.values import now_iso


class Leases:
    """The claims half of ``Store`` (a mixin over its ``transaction``): one process at a time
    writes a participant's session; a dead holder's lease is taken over."""

    # what it needs of the Store it is mixed into (declared, not defined here)
    transaction: Callable[[], AbstractContextManager[Transaction]]

    def acquire_lease(self, participant: str, *, stale_after_s: float = STALE_AFTER_S) -> Lease:
        """Claim ``participant``'s session for this process.

        Raises ``SessionLockedError`` while a live process (or another session object in this
        process) holds it. A lease left by a dead process is taken over; ``Lease.took_over``
        then describes it."""
        token = uuid.uuid4().hex
        pid = os.getpid()
        with self.transaction() as tx:
            tx.require_participant(participant)
            took_over = _require_no_live_holder(tx, participant, stale_after_s=stale_after_s)
            tx.cur.execute(
                "INSERT OR REPLACE INTO leases VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    participant,
                    token,
                    pid,
                    HOST,
                    process_start(pid),
                    now_iso(),
                    time.time(),
                ),
            )
        return Lease(participant=participant, token=token, pid=pid, took_over=took_over)

    def discard_participant(
        self, participant: str, *, stale_after_s: float = STALE_AFTER_S
    ) -> dict[str, int]:
        """Delete everything stored for ``participant`` (samples, trials, ratings, answers, events,
        schedule, session, demographics, enrolment) in one transaction; returns rows deleted
        per table.

        Only for data that can be made again exactly -- ``study simulate --resume`` uses it to
        redo a simulated participant whose run was killed, so the resumed store matches an
        uninterrupted one. Raises ``SessionLockedError`` while a live process holds the
        participant's session, and ``UnknownParticipantError`` if they are not enrolled."""
        with self.transaction() as tx:
            tx.require_participant(participant)
            _require_no_live_holder(tx, participant, stale_after_s=stale_after_s)
            deleted = {
                "samples": tx.cur.execute(
                    "DELETE FROM samples WHERE trial_id IN "
                    "(SELECT trial_id FROM trials WHERE participant = ?)",
                    (participant,),
                ).rowcount
            }
            for table in (
                "ratings", "answers", "events", "trials", "leases", "assignments", "sessions",
                "demographics", "participants",
            ):  # fmt: skip
                deleted[table] = tx.cur.execute(
                    f"DELETE FROM {table} WHERE participant = ?", (participant,)
                ).rowcount
        return deleted

    def heartbeat(self, lease: Lease) -> None:
        """Refresh ``lease``; raises ``SessionLockedError`` if another process took it over."""
        with self.transaction() as tx:
            tx.cur.execute(
                "UPDATE leases SET heartbeat_at = ? WHERE participant = ? AND token = ?",
                (time.time(), lease.participant, lease.token),
            )
            if tx.cur.rowcount != 1:
                raise SessionLockedError(
                    f"participant {lease.participant}'s session lease was taken over by another "
                    "process; this process must stop writing"
                )

    def release_lease(self, lease: Lease) -> None:
        """Give the session back (no error if it was already released)."""
        with self.transaction() as tx:
            tx.cur.execute(
                "DELETE FROM leases WHERE participant = ? AND token = ?",
                (lease.participant, lease.token),
            )


def _require_no_live_holder(
    tx: Transaction, participant: str, *, stale_after_s: float
) -> dict[str, Any] | None:
    """Raise ``SessionLockedError`` while a live process (or this one) holds ``participant``'s
    lease; returns the dead holder's ``{pid, host, acquired_at}``, or ``None`` if no lease."""
    row = tx.cur.execute(
        "SELECT token, pid, host, process_start, acquired_at, heartbeat_at FROM leases "
        "WHERE participant = ?",
        (participant,),
    ).fetchone()
    if row is None:
        return None
    pid = os.getpid()
    _, holder_pid, host, started, acquired_at, heartbeat_at = row
    age = time.time() - heartbeat_at
    if (host == HOST and holder_pid == pid) or holder_is_live(
        pid=holder_pid,
        host=host,
        started=started,
        heartbeat_age_s=age,
        stale_after_s=stale_after_s,
    ):
        where = "this process" if holder_pid == pid else f"process {holder_pid}"
        raise SessionLockedError(
            f"participant {participant}'s session is already open in {where} on "
            f"{host} (since {acquired_at}, last heartbeat {age:.1f} s ago); close it "
            "there first, or wait for that process to exit"
        )
    return {"pid": holder_pid, "host": host, "acquired_at": acquired_at}

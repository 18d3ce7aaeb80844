"""Closing a session object: what is written, what is released, and what a failing disk leaves.

A session closed with a trial running records that trial ``interrupted`` (after committing its
samples) and a ``close`` event; then the sample writer and the lease's heartbeat stop and the
lease is given back, so another process may ``Session.reopen`` it.

If the store refuses writes (full disk, read-only: ``StoreWriteError``) the session is still
closed -- the writer and heartbeat threads stop, nothing more is written -- and the first such
error is raised afterwards. The file then stays consistent: a running trial whose samples could
not be committed stays ``running`` on file, which readers report as interrupted (its ``ticks``
being the samples that did reach the file) and ``Session.reopen`` records as such, so
``--resume`` continues once the disk is fixed.

Called with the session lock held.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from study.session.lease_keeper import LeaseKeeper
from study.session.ledger import Ledger
from study.session.sample_writer import SampleWriter
from study.session.state import RunState
from study.session.trial_run import TrialRun
from study.store import SessionLockedError, StoreError

LOGGER = logging.getLogger("study.session")


def close_session(
    *,
    state: RunState,
    ledger: Ledger,
    writer: SampleWriter,
    keeper: LeaseKeeper,
    stop: Callable[[TrialRun | None], None],
) -> None:
    """Close (see module docstring); idempotent. ``stop`` ends a run and commits its samples."""
    if state.closed:
        return
    errors: list[StoreError] = []
    try:
        if not keeper.lost and not state.finished:
            _record_close(state, ledger, stop, errors)
    finally:
        state.closed = True
        try:
            writer.close()
        except StoreError as exc:
            errors.append(exc)
        try:
            keeper.stop(release=True)
        except StoreError as exc:
            errors.append(exc)
    if errors:
        raise errors[0]


def _record_close(
    state: RunState,
    ledger: Ledger,
    stop: Callable[[TrialRun | None], None],
    errors: list[StoreError],
) -> None:
    where, run = ledger.where(), state.active
    try:
        stop(run)
    except StoreError as exc:
        # The run's last samples are not on file: recording it with run.ticks would claim
        # samples the file does not have, so it is left to the orphan rule (module docstring).
        errors.append(exc)
        return
    try:
        with ledger.suppressed_reported() as report, ledger.tx() as tx:
            if run is not None:
                ledger.record_abort(tx, run, status="interrupted", note="session closed")
            report(tx)
            ledger.event(tx, "close", where)
    except SessionLockedError:
        # Another process took the session over before the keeper noticed: the data are
        # now theirs to write, and there is nothing to release.
        LOGGER.warning("session %s was taken over; closed without writing", ledger.info.participant)
    except StoreError as exc:
        errors.append(exc)


__all__ = ["close_session"]

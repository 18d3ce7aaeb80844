"""``SampleWriter``: batches control-tick records into the store off the control thread.

The control loop calls ``add(trial_id, tick, record)``, which only converts the record to a row
tuple and appends it to a buffer under a short lock (a few microseconds). A background thread,
shared by every writer of the store (``study.session.sample_committer``), commits the buffers
with one ``executemany`` every ``flush_interval_s`` (50 ms by default, at most 250 ms), so a
killed process loses at most the last batch. ``flush()`` commits synchronously (the session
calls it before marking a trial completed). A failed commit keeps the rows buffered and makes
the next ``add``/``flush`` raise, so samples are never dropped silently; the error keeps the
store's type (``StoreFullError`` for a full disk, ``StoreNotWritableError`` for a read-only
one), so callers can tell the experimenter what to do, and the thread keeps retrying, so the
rows held in memory reach the file once space is freed.
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from app.trial import samples as layout
from app.trial.records import TickRecord
from study.session.sample_committer import attach
from study.store import SampleFormatError, Store, StoreError, StoreWriteError

MAX_FLUSH_INTERVAL_S = 0.25
DEFAULT_FLUSH_INTERVAL_S = 0.05
"""A live session's batch period. Batches must reach the store at most ``MAX_FLUSH_INTERVAL_S``
apart; a batch that waits for the CPU or the file's write lock (a loaded 2-core machine with a
browser and four sessions: up to about 130 ms) delays only itself, so the period leaves that
much room. A commit costs about 0.2 ms (no fsync: ``Store.insert_samples``)."""


def sample_row(trial_id: int, tick: int, record: TickRecord) -> tuple[Any, ...]:
    """The ``samples`` row (``SAMPLE_COLUMNS`` order) for one tick record."""
    try:
        return layout.sample_row(trial_id, tick, record)
    except (AttributeError, TypeError, ValueError) as exc:
        raise SampleFormatError(f"tick {tick} cannot be stored as a sample: {exc}") from exc


def _like(error: BaseException, context: str) -> StoreError:
    """A ``StoreError`` of ``error``'s own type (full disk, read-only, ...) with ``context``."""
    if isinstance(error, StoreWriteError):
        return type(error)(f"{context}: {error}", path=error.path)
    return StoreError(f"{context}: {error}")


STATS_KEPT = 4096
"""How many of the latest commits ``WriterStats`` keeps the times of (a live session commits 20
batches a second: the last 3.4 minutes; a list of every one grew 2 MB an hour per session)."""


@dataclass
class WriterStats:
    """What the writer did: rows and batches committed, the longest commit, and the durations
    (s) and end times (``time.monotonic()``) of the latest ``STATS_KEPT`` commits, for gap
    measurements."""

    rows: int = 0
    batches: int = 0
    max_commit_s: float = 0.0
    commit_s: deque[float] = field(default_factory=lambda: deque(maxlen=STATS_KEPT))
    committed_at: deque[float] = field(default_factory=lambda: deque(maxlen=STATS_KEPT))


class SampleWriter:
    """One session's batching sample writer (see module docstring). Thread-safe: ``add``,
    ``flush`` and ``close`` may be called from any thread."""

    def __init__(self, store: Store, *, flush_interval_s: float = DEFAULT_FLUSH_INTERVAL_S) -> None:
        if not 0 < flush_interval_s <= MAX_FLUSH_INTERVAL_S:
            raise StoreError(
                f"flush_interval_s must be in (0, {MAX_FLUSH_INTERVAL_S}] s, not {flush_interval_s}"
            )
        self._buffer: list[tuple[Any, ...]] = []
        self._buffer_lock = threading.Lock()
        self._error: BaseException | None = None
        self._closed = False
        self.stats = WriterStats()
        self._committer = attach(self, store, interval_s=flush_interval_s)

    def add(self, trial_id: int, tick: int, record: TickRecord) -> None:
        """Queue one tick's record (converted now, so a malformed record fails here). If earlier
        commits failed, the row is still queued and ``StoreError`` says so."""
        self.add_row(sample_row(trial_id, tick, record))

    def add_row(self, row: tuple[Any, ...]) -> None:
        """Queue an already converted row (``SAMPLE_COLUMNS`` order)."""
        with self._buffer_lock:
            self._buffer.append(row)
        self._raise_pending()

    @property
    def error(self) -> BaseException | None:
        """Why the last commit failed (``StoreFullError``, ...), or ``None`` once a commit
        succeeded again -- the committer keeps retrying, so this clears by itself when the disk
        has room again."""
        return self._error

    @property
    def pending(self) -> int:
        with self._buffer_lock:
            return len(self._buffer)

    def flush(self) -> int:
        """Commit everything queued so far; returns the number of rows written."""
        before = self.stats.rows
        error = self._committer.commit([self]).get(self)
        if error is not None:
            raise _like(error, f"could not commit {self.pending} samples") from error
        self._raise_pending()
        return self.stats.rows - before

    def close(self) -> None:
        """Leave the committer (its thread ends with the last writer) and commit what is left."""
        if not self._closed:
            self._closed = True
            self._committer.detach(self)
        self.flush()

    # ---- the committer's side (sample_committer.RowQueue) --------------------------------------
    def take_rows(self) -> list[tuple[Any, ...]]:
        with self._buffer_lock:
            rows, self._buffer = self._buffer, []
        return rows

    def put_back(self, rows: list[tuple[Any, ...]], error: BaseException) -> None:
        with self._buffer_lock:
            self._buffer[:0] = rows
        self._error = error

    def note_committed(self, rows: int, elapsed_s: float, at: float) -> None:
        self._error = None
        self.stats.committed_at.append(at)
        self.stats.commit_s.append(elapsed_s)
        self.stats.max_commit_s = max(self.stats.max_commit_s, elapsed_s)
        self.stats.rows += rows
        self.stats.batches += 1

    def _raise_pending(self) -> None:
        error = self._error
        if error is not None:
            raise _like(
                error,
                f"samples are not reaching the store; {self.pending} rows are held in memory and "
                "are written as soon as the store takes writes again (they are lost if this "
                "process ends first)",
            )

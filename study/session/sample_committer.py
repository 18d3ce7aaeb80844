"""``SampleCommitter``: one thread per store that commits every session's queued samples at once.

Each live session's ``SampleWriter`` keeps its own row buffer; the writers of one ``Store`` (and
one batch period) share a committer, whose thread takes every buffer each period and commits all
the rows in one transaction (``Store.insert_samples``). N sessions then cost one commit per period
instead of N commits queuing for the file's single write lock (eight writers on 2 cores held some
batches 0.3-0.76 s apart; see benchmarks/README.md, "Sessions per machine").

A batch that fails is retried writer by writer, so one session's bad rows (a duplicate tick, say)
hold back only that session's samples; a full disk fails them all, and each writer keeps its rows
and its error until a later commit succeeds (``SampleWriter``). The thread ends when its last
writer closes; the next writer of that store starts a new one.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol

from study import scheduling
from study.store import Store

Rows = list[tuple[Any, ...]]


class RowQueue(Protocol):
    """What the committer needs of a writer (``SampleWriter`` has it)."""

    def take_rows(self) -> Rows:
        """Everything queued so far (the queue is then empty)."""
        ...

    def put_back(self, rows: Rows, error: BaseException) -> None:
        """``rows`` could not be stored (``error``): queue them first again."""
        ...

    def note_committed(self, rows: int, elapsed_s: float, at: float) -> None:
        """``rows`` rows reached the store in a commit of ``elapsed_s`` ending at ``at``."""
        ...


_REGISTRY: dict[tuple[int, float], SampleCommitter] = {}
_REGISTRY_LOCK = threading.Lock()


def attach(writer: RowQueue, store: Store, *, interval_s: float) -> SampleCommitter:
    """The running committer of ``store`` for ``interval_s`` (started if there is none), with
    ``writer`` added to the writers it commits."""
    key = (id(store), interval_s)
    with _REGISTRY_LOCK:
        committer = _REGISTRY.get(key)
        if committer is None:
            committer = SampleCommitter(store, interval_s=interval_s)
            _REGISTRY[key] = committer
        committer._writers.append(writer)
    return committer


class SampleCommitter:
    """Commits the rows its writers queued (module docstring). Made by ``attach`` only."""

    def __init__(self, store: Store, *, interval_s: float) -> None:
        self._store = store
        self._interval = interval_s
        self._writers: list[RowQueue] = []  # guarded by _REGISTRY_LOCK
        self._flush_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sample-committer", daemon=True)
        self._thread.start()

    def detach(self, writer: RowQueue) -> None:
        """Stop committing ``writer``'s rows (it flushes what it has itself); the thread ends with
        the last writer."""
        with _REGISTRY_LOCK:
            if writer in self._writers:
                self._writers.remove(writer)
            if self._writers:
                return
            key = (id(self._store), self._interval)
            if _REGISTRY.get(key) is self:
                del _REGISTRY[key]
            self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join()

    def commit(self, writers: list[RowQueue]) -> dict[RowQueue, BaseException]:
        """Commit the rows ``writers`` have queued, in one transaction; returns why each writer
        whose rows could not be stored failed (their rows are back in their buffers)."""
        with self._flush_lock:
            taken = [(w, rows) for w in writers if (rows := w.take_rows())]
            if not taken:
                return {}
            if len(taken) > 1 and self._insert(taken) is None:
                return {}
            failed: dict[RowQueue, BaseException] = {}
            for writer, rows in taken:  # one by one: only the writers at fault keep failing
                error = self._insert([(writer, rows)])
                if error is not None:
                    failed[writer] = error
            return failed

    def _insert(self, taken: list[tuple[RowQueue, Rows]]) -> BaseException | None:
        start = time.perf_counter()
        try:
            self._store.insert_samples([row for _, rows in taken for row in rows])
        except Exception as exc:
            if len(taken) == 1:
                taken[0][0].put_back(taken[0][1], exc)
            return exc
        elapsed = time.perf_counter() - start
        now = time.monotonic()
        for writer, rows in taken:
            writer.note_committed(len(rows), elapsed, now)
        return None

    def _run(self) -> None:
        scheduling.enter_timekeeping()  # a commit due runs ahead of the rest of the server
        # Deadlines on a fixed grid, not "sleep after each commit": a slow commit then delays
        # only its own batch, and the next one follows at once instead of a full period later.
        due = time.monotonic()
        while True:
            due += self._interval
            now = time.monotonic()
            if due < now:  # fell behind by more than a period: start the grid again from now
                due = now
            if self._stop.wait(max(0.0, due - now)):
                return
            with _REGISTRY_LOCK:
                writers = list(self._writers)
            # Failures stay with their writers (reported by their next add/flush); retried next
            # period.
            self.commit(writers)

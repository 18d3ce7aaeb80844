"""``LeaseKeeper``: refreshes a session lease's heartbeat from a background thread."""

from __future__ import annotations

import threading

from study.store import Lease, SessionLockedError, Store, StoreError


class LeaseKeeper:
    """Calls ``store.heartbeat(lease)`` every ``interval_s``; ``lost`` turns true if another
    process took the lease over (the session then refuses to write)."""

    def __init__(self, store: Store, lease: Lease, *, interval_s: float = 2.0) -> None:
        self.store = store
        self.lease = lease
        self.lost = False
        self._interval = interval_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lease-heartbeat", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._interval):
            try:
                self.store.heartbeat(self.lease)
            except SessionLockedError:
                self.lost = True
                return
            except StoreError:
                continue  # store busy or closing: try again next period

    def stop(self, *, release: bool) -> None:
        """Stop the thread; with ``release`` give the lease back."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join()
        if release and not self.lost:
            self.store.release_lease(self.lease)

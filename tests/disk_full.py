"""Making a store "full" for tests: SQLite's own ``SQLITE_FULL``, without filling a disk.

``PRAGMA max_page_count`` caps how large a connection lets the file grow; past it, writes fail
with "database or disk is full" exactly as on a full file system. The cap is per connection, so
both of a store's connections (its main one and the samples' own) are capped.
"""

from __future__ import annotations

from study.store import Store

NO_CAP = 1073741823  # SQLite's default max_page_count


def cap(store: Store, *, extra_pages: int) -> None:
    """Let ``store``'s file grow by ``extra_pages`` pages only, from now on."""
    connections = [store.conn, store._sample_connection()]  # the store's private test hook
    pages = store.conn.execute("PRAGMA page_count").fetchone()[0]
    for conn in connections:
        conn.execute(f"PRAGMA max_page_count = {pages + extra_pages}")


def uncap(store: Store) -> None:
    """Space is free again."""
    for conn in (store.conn, store._sample_connection()):
        conn.execute(f"PRAGMA max_page_count = {NO_CAP}")

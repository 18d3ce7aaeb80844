"""Opening the study store for a protocol, and checking a store belongs to the protocol."""

from __future__ import annotations

from pathlib import Path

from study.protocol import Protocol
from study.store import ProtocolMismatchError, Store, changed_sections


def open_store(
    path: str | Path, protocol: Protocol, *, synchronous: str = "FULL", verify: bool = True
) -> Store:
    """Open (or create) the store at ``path`` for ``protocol``; a new store keeps the protocol's
    full text, so export and analysis can rebuild it (``study.protocol.protocol_from_store``).

    Raises ``ProtocolMismatchError`` (naming both content hashes and the changed sections) if
    the store was started with another protocol: continue with the original file, or use a new
    path for the edited protocol; ``StoreDamagedError`` if SQLite finds an existing file
    damaged (``verify=False`` skips that check: a worker opening a store its parent checked)."""
    return Store.open(
        path,
        protocol_id=protocol.id,
        protocol_hash=protocol.content_hash,
        protocol_version=protocol.study.version,
        protocol_text=protocol.source or None,
        synchronous=synchronous,
        verify=verify,
    )


def check_protocol(store: Store, protocol: Protocol) -> None:
    """Raise ``ProtocolMismatchError`` unless ``store`` was started with ``protocol``."""
    meta = store.meta
    if meta.protocol_hash != protocol.content_hash or meta.protocol_id != protocol.id:
        changed = changed_sections(store.protocol_text(), protocol.source or None)
        raise ProtocolMismatchError(
            f"store {store.path} was written by protocol {meta.protocol_id!r} version "
            f"{meta.protocol_version or '?'} (content hash {meta.protocol_hash}), not by "
            f"{protocol.id!r} version {protocol.study.version} (content hash "
            f"{protocol.content_hash}){f'; changed: {changed}' if changed else ''}; use the "
            "protocol the study started with (study.protocol.protocol_from_store rebuilds it), "
            "or a new store for the edited protocol (data untouched)"
        )


__all__ = ["check_protocol", "open_store"]

"""``protocol_from_store(store) -> Protocol``: the exact protocol a study store was run with.

The store keeps the protocol's TOML text keyed by its content hash (``Store.protocol_text``).
Rebuilding from it does not depend on the protocol file still existing or being unedited; the
rebuilt protocol's content hash must equal the store's, else the stored text was tampered with.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from study.protocol.errors import ProtocolError
from study.protocol.loader import parse_protocol

if TYPE_CHECKING:
    from study.protocol.protocol import Protocol
    from study.store import Store


class StoredProtocolError(ProtocolError):
    """The store holds no usable protocol text (an old store, or text that no longer loads)."""


def protocol_from_store(store: Store) -> Protocol:
    """The protocol ``store`` was created for, parsed and validated from the text it keeps.

    Raises ``StoredProtocolError`` if the store has no protocol text (made by schema version 1
    or without ``protocol_text``: pass the protocol file instead), or if the text's content hash
    differs from the store's; a ``ProtocolError`` from validation if this software no longer
    accepts the text (e.g. a changed scene format: use the platform version that ran the study).
    """
    where = f"{store.path} (stored protocol)"
    text = store.protocol_text()
    if text is None:
        raise StoredProtocolError(
            f"the store does not keep its protocol's text (protocol {store.meta.protocol_id!r}, "
            f"content hash {store.meta.protocol_hash}); pass the protocol file the study ran with",
            file=store.path,
            key="",
        )
    protocol = parse_protocol(text, path=where)
    if protocol.content_hash != store.meta.protocol_hash:
        raise StoredProtocolError(
            f"the stored protocol text has content hash {protocol.content_hash}, but the store "
            f"was written by {store.meta.protocol_hash}; the file was altered outside the "
            "platform: pass the protocol file the study ran with",
            file=store.path,
            key="protocols",
        )
    return protocol

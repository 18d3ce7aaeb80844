"""Which protocol a store was run with: the text it keeps, else a matching protocol file."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from study.protocol import (
    ProtocolError,
    load_protocol,
    protocol_from_store,
)
from study.store import Store

if TYPE_CHECKING:
    from study.protocol import Protocol


def resolve_protocol(
    store: Store, *, search: Sequence[Path] | None = None
) -> tuple[Protocol | None, str]:
    """The protocol ``store`` was run with and where it came from, in this order: the text the
    store keeps (``"store"``); a protocol file with the same content hash (``"file <path>"``,
    see ``find_protocol``); else ``None`` and why, in which case export infers the items from
    the data (7-point scale, preference re-centred on ``aggressive`` or on the alphabetically
    last of two modes)."""
    try:
        return protocol_from_store(store), "store"
    except ProtocolError as exc:
        why = str(exc)
    found = find_protocol(store, search=search)
    if found is not None:
        return found, f"file {found.path}"
    return None, f"{why}; no protocol file matches either, so item columns are inferred"


def find_protocol(store: Store, *, search: Sequence[Path] | None = None) -> Protocol | None:
    """The protocol file that wrote ``store`` (same study id and content hash), if one is found
    as ``<dir>/<study id>.toml`` in ``search`` (default: ./protocols and the repository's)."""
    dirs = (
        search
        if search is not None
        else (Path("protocols"), Path(__file__).resolve().parents[2] / "protocols")
    )
    for d in dirs:
        path = d / f"{store.meta.protocol_id}.toml"
        if path.is_file():
            try:
                p = load_protocol(path)
            except ProtocolError:
                continue
            if p.content_hash == store.meta.protocol_hash:
                return p
    return None

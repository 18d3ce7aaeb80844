"""``metadata.json``: the provenance of an export and who was left out of it, and why."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import pandas as pd

import app
from study.retention import UNDER_WAY
from study.store import Store, now_iso

if TYPE_CHECKING:
    from study.protocol import Protocol


def excluded_participants(tables: Mapping[str, pd.DataFrame]) -> dict[str, str]:
    """``{participant: why}`` for everyone left out of the tables (``participants``)."""
    p = tables.get("participants")
    if p is None or p.empty:
        return {}
    out = p[~p["included"].astype(bool)]
    return dict(zip(out["participant"], out["excluded_because"].astype(str), strict=True))


def retention_pending(tables: Mapping[str, pd.DataFrame]) -> list[str]:
    """Included participants whose session has not reached the retention question yet."""
    p = tables.get("participants")
    if p is None or p.empty:
        return []
    under_way = p["included"].astype(bool) & p["status"].isin(UNDER_WAY) & p["retention"].isna()
    return [str(x) for x in p.loc[under_way, "participant"]]


def export_metadata(
    store: Store, tables: Mapping[str, pd.DataFrame], *, protocol: Protocol | None
) -> dict[str, Any]:
    """Provenance written beside the tables as ``metadata.json``: which store, protocol (id,
    version, content hash, whether the store keeps its text) and software produced them, how
    many rows each table has, ``orphaned_trials``: trials left running by a process that
    died, exported as interrupted (resuming their sessions records that in the store), and
    ``excluded_participants``: who was left out and why (data retention), and
    ``retention_pending``: who was exported while their session is still under way.
    ``write_export`` adds ``formats``, the table file formats it wrote."""
    return {
        "store": str(store.path),
        "store_schema": store.meta.version,
        "protocol_id": store.meta.protocol_id,
        "protocol_version": store.meta.protocol_version,
        "protocol_hash": store.meta.protocol_hash,
        "protocol_file": str(protocol.path) if protocol is not None else None,
        "protocol_stored": store.protocol_text() is not None,
        "software_version": app.__version__,
        "exported_at": now_iso(),
        "rows": {name: len(df) for name, df in tables.items()},
        "orphaned_trials": store.orphaned_trials(),
        "excluded_participants": excluded_participants(tables),
        "retention_pending": retention_pending(tables),
    }

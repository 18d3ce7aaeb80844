"""Writing an export: the tables as CSV and/or Parquet, the codebook, the protocol's text and
``metadata.json``, staged in a hidden folder and moved in so a failed export leaves nothing half
written."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from study.codebook import write_codebook
from study.export.columns import TABLE_NAMES
from study.export.errors import ExportError

EXPORT_FORMATS = ("csv", "parquet")
"""Table file formats an export can write, as ``<table>.<format>``."""

EXPORT_EXTRAS = ("codebook.csv", "codebook.md", "metadata.json", "protocol.toml")
"""The other files an export writes beside the tables."""


def _check_formats(formats: Sequence[str]) -> tuple[str, ...]:
    unknown = [f for f in formats if f not in EXPORT_FORMATS]
    if unknown or not formats:
        raise ExportError(
            f"export formats must be one or both of {', '.join(EXPORT_FORMATS)}, got"
            f" {list(formats)}"
        )
    return tuple(dict.fromkeys(formats))


def _write_table_files(
    tables: Mapping[str, pd.DataFrame], out_dir: Path, formats: tuple[str, ...]
) -> list[Path]:
    written: list[Path] = []
    for name, df in tables.items():
        if "csv" in formats:
            path = out_dir / f"{name}.csv"
            df.to_csv(path, index=False)
            written.append(path)
        if "parquet" in formats:
            path = out_dir / f"{name}.parquet"
            df.to_parquet(path, index=False)
            written.append(path)
    return written


def stale_export_files(
    out: str | os.PathLike[str], *, formats: Sequence[str], protocol_text: bool = True
) -> list[Path]:
    """Files of an earlier export in ``out`` that an export of ``formats`` would not overwrite:
    ``<table>.<format>`` of the other formats (and ``protocol.toml`` when this export writes
    none). Only names an export writes are considered; other files are never listed."""
    out_dir = Path(out)
    others = [f for f in EXPORT_FORMATS if f not in formats]
    stale = [out_dir / f"{name}.{f}" for name in TABLE_NAMES for f in others]
    if not protocol_text:
        stale.append(out_dir / "protocol.toml")
    return [p for p in stale if p.is_file()]


def write_export(
    out: str | os.PathLike[str],
    tables: Mapping[str, pd.DataFrame],
    *,
    codebook: pd.DataFrame,
    metadata: Mapping[str, Any],
    protocol_text: str | None,
    formats: Sequence[str] = EXPORT_FORMATS,
) -> list[Path]:
    """Write a whole export into ``out``: the tables in ``formats``, ``codebook.csv``/``.md``,
    ``protocol.toml`` (when ``protocol_text`` is given) and ``metadata.json`` (``metadata`` plus
    ``formats``, the table formats written). Returns the paths written.

    Everything is first written into a hidden folder inside ``out`` and then moved in, with
    ``metadata.json`` last, so a failed export leaves ``out`` as it was. Files of an earlier
    export that this one does not replace (tables of another format, a ``protocol.toml``) are
    removed; files an export does not write are left alone."""
    formats = _check_formats(formats)
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".export-", dir=out_dir))
    try:
        staged = _write_table_files(tables, staging, formats)
        staged += write_codebook(codebook, staging)
        if protocol_text is not None:
            path = staging / "protocol.toml"
            path.write_text(protocol_text, encoding="utf-8")
            staged.append(path)
        meta_staged = staging / "metadata.json"
        meta = {**metadata, "formats": list(formats)}
        meta_staged.write_text(json.dumps(meta, indent=1) + "\n")
        # the old metadata goes first: a folder without it is never mistaken for a whole export
        (out_dir / "metadata.json").unlink(missing_ok=True)
        written = []
        for path in staged:
            os.replace(path, out_dir / path.name)
            written.append(out_dir / path.name)
        for path in stale_export_files(
            out_dir, formats=formats, protocol_text=protocol_text is not None
        ):
            path.unlink()
        os.replace(meta_staged, out_dir / "metadata.json")
        written.append(out_dir / "metadata.json")
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return written

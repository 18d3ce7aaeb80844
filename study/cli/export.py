"""``python -m study export --db PATH --out DIR``: tidy CSV + Parquet tables and a codebook.

Writes trials, samples, ratings and events (``.csv`` and ``.parquet``) and ``codebook.csv`` /
``codebook.md`` describing every column, and ``metadata.json`` (store, protocol id, version and
content hash, software version, row counts). The store is opened read-only.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from study.codebook import codebook, write_codebook
from study.export import (
    ExportError,
    export_metadata,
    find_protocol,
    tidy_tables,
    write_tables,
)
from study.protocol import ProtocolError, load_protocol
from study.store import Store, StoreError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--db", type=Path, required=True, help="the study's SQLite store")
    parser.add_argument("--out", type=Path, required=True, help="directory to write into")
    parser.add_argument(
        "--protocol", type=Path, default=None,
        help="protocol the study ran with (default: protocols/<study id>.toml if it matches)",
    )
    parser.add_argument(
        "--format", choices=("both", "csv", "parquet"), default="both", help="file formats"
    )


def main(args: argparse.Namespace) -> int:
    formats = ("csv", "parquet") if args.format == "both" else (args.format,)
    try:
        with Store.open_readonly(args.db) as store:
            protocol = (
                load_protocol(args.protocol) if args.protocol else find_protocol(store)
            )
            if protocol is None:
                print(
                    f"note: no protocol file matches the store's protocol"
                    f" {store.meta.protocol_id!r} (hash {store.meta.protocol_hash[:12]}); item"
                    " columns are inferred from the data (pass --protocol with the file the study ran with)",
                    file=sys.stderr,
                )
            tables = tidy_tables(store, protocol=protocol, search=[])
            metadata = export_metadata(store, tables, protocol=protocol)
        book = codebook(tables, protocol=protocol)
        written = write_tables(tables, args.out, formats=formats)
        written += write_codebook(book, args.out)
        meta_path = Path(args.out) / "metadata.json"
        meta_path.write_text(json.dumps(metadata, indent=1) + "\n")
        written.append(meta_path)
    except (StoreError, ProtocolError, ExportError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps({"out": str(args.out), "rows": metadata["rows"], "files": len(written),
                      "protocol": metadata["protocol_file"]}))
    return 0

"""``python -m study export --db PATH --out DIR``: tidy CSV + Parquet tables and a codebook.

Writes trials, samples, ratings and events (``.csv`` and ``.parquet``) and ``codebook.csv`` /
``codebook.md`` describing every column, ``metadata.json`` (store, protocol id, version and
content hash, software version, row counts, table formats) and ``protocol.toml``, the exact
protocol text the store keeps. Exporting again into the same folder replaces an earlier export's files, removing
the ones this export does not write (e.g. the Parquet tables on ``--format csv``); other files
are left alone. The store is opened read-only. Item columns follow the protocol the store keeps;
``--protocol`` overrides it (it must have the same content hash).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from study.cli.arguments import output_dir
from study.codebook import codebook
from study.export import (
    export_metadata,
    resolve_protocol,
    tidy_tables,
    write_export,
)
from study.protocol import load_protocol
from study.store import Store


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--db", type=Path, required=True, help="the study's SQLite store")
    parser.add_argument("--out", type=output_dir, required=True, help="directory to write into")
    parser.add_argument(
        "--protocol",
        type=Path,
        default=None,
        help="protocol the study ran with (default: the one the store keeps, else "
        "protocols/<study id>.toml if its content hash matches)",
    )
    parser.add_argument(
        "--format", choices=("both", "csv", "parquet"), default="both", help="file formats"
    )


def main(args: argparse.Namespace) -> int:
    formats = ("csv", "parquet") if args.format == "both" else (args.format,)
    try:
        with Store.open_readonly(args.db, verify=True) as store:  # a damaged file: said so
            if args.protocol:
                protocol, source = load_protocol(args.protocol), f"file {args.protocol}"
            else:
                protocol, source = resolve_protocol(store)
            if source != "store":
                print(f"note: protocol from {source}", file=sys.stderr)
            tables = tidy_tables(store, protocol=protocol, search=[])
            metadata = export_metadata(store, tables, protocol=protocol)
            stored_text = store.protocol_text()
            if metadata["orphaned_trials"]:
                print(
                    f"note: trials {metadata['orphaned_trials']} were left running by a process "
                    "that died; they are exported as interrupted (resume those sessions to "
                    "record it, or leave them)",
                    file=sys.stderr,
                )
            for participant, why in metadata["excluded_participants"].items():
                print(f"note: {participant} left out: {why}", file=sys.stderr)
            if metadata["retention_pending"]:
                print(
                    f"note: {', '.join(metadata['retention_pending'])}: session still under way,"
                    " exported as it stands; whether their data may be kept is asked at its end"
                    " (export again then)",
                    file=sys.stderr,
                )
        book = codebook(tables, protocol=protocol)
        written = write_export(
            args.out,
            tables,
            codebook=book,
            metadata=metadata,
            protocol_text=stored_text,
            formats=formats,
        )
    except OSError as e:  # the folder to write into (StudyErrors are said by the dispatcher)
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(
        json.dumps(
            {
                "out": str(args.out),
                "rows": metadata["rows"],
                "files": len(written),
                "protocol": metadata["protocol_file"],
                "excluded_participants": len(metadata["excluded_participants"]),
            }
        )
    )
    return 0

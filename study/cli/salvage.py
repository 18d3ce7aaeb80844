"""``python -m study salvage``: copy what is readable of a damaged store into a new store.

    python -m study salvage --db data/study.db --out data/study-salvaged.db

A store that SQLite finds damaged is refused by every command that would write to it (the
error names this command). Salvage reads it (never writes it), copies every readable row into
the new store with the same identity and protocol, and prints one JSON line: rows copied and
key ranges lost per table, and rows whose parent row was lost. Continue the study with
``--db`` naming the new store; keep the damaged file for the record.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from study.cli.arguments import output_file
from study.store.salvage import salvage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--db", type=Path, required=True, help="the damaged store (read only)")
    parser.add_argument("--out", type=output_file, required=True, help="the new store to write")


def main(args: argparse.Namespace) -> int:
    report = salvage(args.db, args.out)
    lost = sum(len(t.lost_ranges) for t in report.tables.values())
    copied = sum(t.copied for t in report.tables.values())
    print(
        f"copied {copied} rows into {args.out}"
        + (f"; {lost} key range(s) could not be read" if lost else "; nothing was lost"),
        file=sys.stderr,
    )
    print(json.dumps(report.as_dict()))
    return 0

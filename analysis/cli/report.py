"""``python -m analysis report``: the study report from a store or an export directory.

Writes OUT/report.html (self-contained), OUT/report.md, OUT/results.json and OUT/figures/.
"""

from __future__ import annotations

import argparse
import sys
import time

from analysis.cli import fail, friendly, note
from analysis.load import load_tables
from analysis.protocol_info import DEFAULT_PROTOCOL, ROOT
from analysis.report import write_report
from study.cli.arguments import output_dir


def add_arguments(parser: argparse.ArgumentParser) -> None:
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--db", help="the study's SQLite store")
    src.add_argument("--export-dir", help="a folder written by `python -m study export`")
    parser.add_argument(
        "--out", type=output_dir, required=True, help="output folder (created if needed)"
    )
    parser.add_argument(
        "--protocol",
        default=None,
        help="protocol TOML the study ran with (Fig. 7, the hash, factor levels "
        "and predictors), read only if the store or export keeps no "
        f"protocol text (default: {DEFAULT_PROTOCOL.relative_to(ROOT)})",
    )
    parser.add_argument(
        "--successful-only",
        action="store_true",
        help="leave out completed trials that ended without success",
    )


@friendly
def main(args: argparse.Namespace) -> int:

    start = time.perf_counter()
    tables = load_tables(db=args.db, export_dir=args.export_dir)
    if tables.trials.empty:
        return fail(f"{tables.source} holds no trials; run a study (or a simulation) first")
    files = write_report(
        tables, args.out, protocol_path=args.protocol, successful_only=args.successful_only
    )
    for n in files.results.notes:
        note(n)
    print(
        f"wrote {files.html}, {files.markdown}, {files.results_json} and "
        f"{len(files.figures)} figure files in {time.perf_counter() - start:.1f} s",
        file=sys.stderr,
    )
    print(files.html)
    return 0

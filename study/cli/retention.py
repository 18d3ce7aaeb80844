"""``python -m study retention --db PATH --participant ID --keep yes|no``: record a data-retention
answer given in person after a session stopped.

The page asks the protocol's retention question at the end of the study; a participant who
withdrew (or whose session was ended) never saw it, and their data are left out of export and
analysis until they agree (``study.retention``). When the experimenter asks them in person,
this records their answer, marked as recorded by the experimenter. The store must have been
written with a protocol that asks the question (the store keeps it).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from study.protocol import protocol_from_store
from study.retention import record_retention
from study.session import open_store
from study.store import Store


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--db", type=Path, required=True, help="the study's SQLite store")
    parser.add_argument("--participant", required=True, help="the participant's ID")
    parser.add_argument(
        "--keep",
        choices=("yes", "no"),
        required=True,
        help="yes: they agree that their recorded runs and answers are kept and used",
    )


def main(args: argparse.Namespace) -> int:
    with Store.open_readonly(args.db) as store:
        protocol = protocol_from_store(store)
    with open_store(args.db, protocol) as store:
        option = record_retention(store, protocol, args.participant, keep=args.keep == "yes")
    print(json.dumps({"participant": args.participant, "recorded": option}))
    return 0

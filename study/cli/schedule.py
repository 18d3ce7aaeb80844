"""``python -m study schedule``: print the counterbalanced schedule of task trials.

One row per trial (training excluded) with columns ``participant, position, task, mode``::

    python -m study schedule --protocol protocols/dragan2013.toml --participants 8 --format csv
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
from pathlib import Path

from study.cli.arguments import int_range
from study.protocol import load_protocol
from study.schedule import Design, ScheduleError, schedule

DEFAULT_PROTOCOL = Path(__file__).resolve().parents[2] / "protocols" / "dragan2013.toml"
COLUMNS = ("participant", "position", "task", "mode")
MAX_PARTICIPANTS = 10_000
"""Most participants a printed schedule covers (the protocol's own count may be larger)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--protocol",
        type=Path,
        default=DEFAULT_PROTOCOL,
        help="protocol TOML file (default: the repository's protocols/dragan2013.toml)",
    )
    parser.add_argument(
        "--participants",
        type=int_range(1, MAX_PARTICIPANTS),
        default=None,
        help=f"number of participants, 1..{MAX_PARTICIPANTS} (default: the protocol's"
        " study.participants)",
    )
    parser.add_argument("--format", choices=("csv", "json"), default="csv", help="output format")


def main(args: argparse.Namespace) -> int:
    protocol = load_protocol(args.protocol)
    participants = args.participants
    if participants is None:
        participants = protocol.study.participants
        if participants is None:
            raise ScheduleError(
                f"{args.protocol} sets no study.participants; pass --participants N"
            )
    trials = schedule(protocol, participants=participants)
    design = Design.from_protocol(protocol)
    if participants % design.cycle:
        print(
            f"note: {participants} participants leave the last cycle unbalanced; whole balanced"
            f" cycles are multiples of {design.cycle} ({design.cycle_parts})",
            file=sys.stderr,
        )
    between = protocol.between_factors  # a column each, after the participant
    columns = (COLUMNS[0], *between, *COLUMNS[1:])
    records = [
        {
            **{c: getattr(t, c) for c in COLUMNS},
            **{f: protocol.group_for(t.row).levels[f] for f in between},
        }
        for t in trials
    ]
    records = [{c: r[c] for c in columns} for r in records]
    if args.format == "json":
        text = json.dumps(records, indent=1) + "\n"
    else:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(records)
        text = buffer.getvalue()
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:  # e.g. piped into `head`: the reader has all it wanted
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
    return 0

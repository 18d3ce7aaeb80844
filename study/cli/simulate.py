"""``python -m study simulate``: simulated participants through the whole study, headless.

    python -m study simulate --protocol protocols/dragan2013.toml --participants 8 \\
        --db data/sim.db --seed 1 [--workers N] [--population protocols/population.toml] \\
        [--resume] [--engine local|dask] [--scheduler tcp://HOST:PORT]

Every participant is drawn from the population file, enrolled, and driven through the real
session engine and control loop (training, every task in both modes, questionnaires, debrief)
as fast as the machine allows, writing the same store as a live study. Progress bars go to
stderr (participants overall, trials of each participant running); the last line on stdout is
one JSON object: participants, trials, ratings, wall_s
(plus workers, db, seed, simulated_s, outcomes, errors; kept and redone after --resume; error
when the store took no more writes). Exit code 2 on bad input, when a participant's session
failed, or when the disk filled up or turned read-only: free space and re-run with --resume.

Engines: ``local`` runs in this process or ``--workers`` processes sharing the store; ``dask``
runs each participant as a Dask task on a ``LocalCluster`` of ``--workers`` processes, or on the
existing cluster at ``--scheduler``, and this process alone writes the store, participant by
participant in order (``study.simulated.dask_engine``). Both give the same data for a seed. An
unreachable scheduler is an error naming its address (exit code 2) within a few seconds.

A killed run is continued by the same command with ``--resume``: completed participants are
kept, an unfinished one is simulated again from its start, so the store ends up with the data an
uninterrupted run with the same seed would have written.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from study.cli.arguments import int_range, scheduler_address, seed
from study.errors import StudyError
from study.protocol import load_protocol
from study.protocol.preflight import check_scenes
from study.simulated.runner import simulate

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_PROTOCOL = ROOT / "protocols" / "dragan2013.toml"
DEFAULT_POPULATION = ROOT / "protocols" / "population.toml"
MAX_PARTICIPANTS = 100_000
MAX_WORKERS = 256


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--protocol", type=Path, default=DEFAULT_PROTOCOL, help="protocol TOML")
    parser.add_argument("--db", type=Path, required=True, help="study store (SQLite file)")
    parser.add_argument(
        "--participants",
        type=int_range(1, MAX_PARTICIPANTS),
        default=8,
        help=f"how many to simulate, 1..{MAX_PARTICIPANTS}",
    )
    parser.add_argument("--seed", type=seed, default=0, help="population + session seed")
    parser.add_argument(
        "--workers",
        type=int_range(1, MAX_WORKERS),
        default=1,
        help="processes: local engine, each writes the same WAL store; dask engine without "
        "--scheduler, the LocalCluster's workers",
    )
    parser.add_argument(
        "--engine",
        choices=["local", "dask"],
        default="local",
        help="local: this machine's processes; dask: a Dask cluster, this process the only writer",
    )
    parser.add_argument(
        "--scheduler",
        type=scheduler_address,
        default=None,
        metavar="ADDRESS",
        help="--engine dask: an existing scheduler (tcp://HOST:PORT); without it a LocalCluster",
    )
    parser.add_argument(
        "--population", type=Path, default=DEFAULT_POPULATION, help="population TOML"
    )
    parser.add_argument(
        "--first",
        type=int_range(0, 10**9),
        default=0,
        help="first population index (to add to a store)",
    )
    parser.add_argument(
        "--synchronous",
        choices=["FULL", "NORMAL"],
        default="NORMAL",
        help="SQLite durability (NORMAL: safe against a crash of the process, not of the OS)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue a killed run (same arguments): keep completed participants, redo "
        "unfinished ones from their start",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    result: dict[str, Any]
    try:
        check_scenes(load_protocol(args.protocol))  # every scene builds, before anything runs
        report = simulate(
            protocol_path=args.protocol,
            db=args.db,
            participants=args.participants,
            seed=args.seed,
            workers=args.workers,
            population_path=args.population,
            first=args.first,
            synchronous=args.synchronous,
            progress=not args.no_progress,
            resume=args.resume,
            engine=args.engine,
            scheduler=args.scheduler,
        )
        result = report.as_dict()
        for error in report.errors:
            print(f"error: {error}", file=sys.stderr)
        if report.error is not None:
            print(f"error: {report.error}", file=sys.stderr)
        code = 2 if report.errors or report.error is not None else 0
    except StudyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        result = {"participants": 0, "trials": 0, "ratings": 0, "wall_s": 0.0, "error": str(exc)}
        code = 2
    except KeyboardInterrupt:
        print(
            "interrupted: completed participants are in the store (a running trial is marked "
            "interrupted); continue with the same command and --resume",
            file=sys.stderr,
        )
        result = {"status": "interrupted"}
        code = 130
    print(json.dumps(result))
    return code

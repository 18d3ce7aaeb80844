"""``python -m study sweep``: calibrate the arbitration modes by the paper's two criteria.

    python -m study sweep --out data/sweep [--participants 8] [--seed 1] \\
        [--timid-alpha-max 0.2 0.3 0.4 0.5 0.6] [--aggressive-threshold 0.2 0.4 0.6] \\
        [--aggressive-alpha-high 0.7 0.9 1.0] [--confidence-D 0.2 0.28 0.4] \\
        [--min-hard-completion 0.8] \\
        [--min-wrong-corrected 0.8] [--max-time-lost 10] \\
        [--engine local|dask] [--workers N] [--scheduler tcp://HOST:PORT]

Runs every setting (and the protocol's current ones) through the same simulated participants,
judges each (``study.sweep.criteria``): timid = least help with hard-task completion at least
``--min-hard-completion``; aggressive = most help with wrong trials completed at least
``--min-wrong-corrected`` and at most ``--max-time-lost`` seconds lost to the wrong prediction.
``--confidence-D`` runs the protocol's own two modes at each distance-confidence ``D`` too
(``c = max(0, 1 - d / D)``), judged by the same criteria and never picked.
Prints the table (stdout), writes ``sweep.csv``, ``sweep.json``, ``chosen.toml`` and
``sweep.png`` into ``--out`` (with the variant protocols and their stores: the same command run
again continues where it stopped), and prints one JSON line last: the picks and the verdict on
the protocol's current values. Exit code 2 on bad input or a failed simulation.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from study.cli.arguments import float_range, int_range, output_dir, scheduler_address, seed
from study.cli.simulate import DEFAULT_POPULATION, DEFAULT_PROTOCOL, MAX_WORKERS
from study.errors import StudyError
from study.protocol import load_protocol
from study.protocol.preflight import check_scenes
from study.sweep import Criteria, make_grid, sweep
from study.sweep.criteria import (
    DEFAULT_MAX_TIME_LOST_S,
    DEFAULT_MIN_HARD_COMPLETION,
    DEFAULT_MIN_WRONG_CORRECTED,
)
from study.sweep.grid import (
    DEFAULT_AGGRESSIVE_ALPHA_HIGH,
    DEFAULT_AGGRESSIVE_THRESHOLD,
    DEFAULT_TIMID_ALPHA_MAX,
)
from study.sweep.report import table, write

unit = float_range(0.0, 1.0)
"""A share or an arbitration setting, 0..1."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--protocol", type=Path, default=DEFAULT_PROTOCOL, help="protocol TOML")
    parser.add_argument(
        "--out", type=output_dir, required=True, help="folder for evidence and stores"
    )
    parser.add_argument(
        "--participants", type=int_range(1, 10_000), default=8, help="per setting, 1..10000"
    )
    parser.add_argument("--seed", type=seed, default=1, help="population + sessions")
    parser.add_argument("--population", type=Path, default=DEFAULT_POPULATION)
    grid = parser.add_argument_group("grid")
    grid.add_argument(
        "--timid-alpha-max", type=unit, nargs="+", default=list(DEFAULT_TIMID_ALPHA_MAX)
    )
    grid.add_argument(
        "--aggressive-threshold", type=unit, nargs="+", default=list(DEFAULT_AGGRESSIVE_THRESHOLD)
    )
    grid.add_argument(
        "--aggressive-alpha-high",
        type=unit,
        nargs="+",
        default=list(DEFAULT_AGGRESSIVE_ALPHA_HIGH),
    )
    grid.add_argument(
        "--confidence-D",
        dest="confidence_D",
        type=float_range(0.0, 10.0, above=True),
        nargs="+",
        default=[],
        metavar="D",
        help="m: the protocol's two modes at each D of the distance confidence",
    )
    crit = parser.add_argument_group("criteria")
    crit.add_argument("--min-hard-completion", type=unit, default=DEFAULT_MIN_HARD_COMPLETION)
    crit.add_argument("--min-wrong-corrected", type=unit, default=DEFAULT_MIN_WRONG_CORRECTED)
    crit.add_argument(
        "--max-time-lost",
        type=float_range(0.0, 3600.0),
        default=DEFAULT_MAX_TIME_LOST_S,
        help="seconds",
    )
    parser.add_argument("--engine", choices=["local", "dask"], default="local")
    parser.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=1)
    parser.add_argument("--scheduler", type=scheduler_address, default=None, metavar="ADDRESS")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def main(args: argparse.Namespace) -> int:
    summary: dict[str, Any]
    try:
        check_scenes(load_protocol(args.protocol))  # every scene builds, before anything runs
        grid = make_grid(
            timid_alpha_max=tuple(args.timid_alpha_max),
            aggressive_threshold=tuple(args.aggressive_threshold),
            aggressive_alpha_high=tuple(args.aggressive_alpha_high),
        )
        result = sweep(
            protocol_path=args.protocol,
            out=args.out,
            grid=grid,
            participants=args.participants,
            seed=args.seed,
            criteria=Criteria(
                min_hard_completion=args.min_hard_completion,
                min_wrong_corrected=args.min_wrong_corrected,
                max_time_lost_s=args.max_time_lost,
            ),
            engine=args.engine,
            workers=args.workers,
            scheduler=args.scheduler,
            population_path=args.population,
            progress=not args.no_progress,
            confidence_D=tuple(args.confidence_D),
        )
        paths = write(result, args.out)
        print(table(result))
        for error in result.errors:
            print(f"error: {error}", file=sys.stderr)
        summary = {
            "settings": len(result.measures),
            "participants": result.participants,
            "chosen": {
                mode: None if m is None else m.setting.label for mode, m in result.chosen.items()
            },
            "today": result.verdict(),
            "files": {k: str(v) for k, v in paths.items()},
            "errors": list(result.errors),
        }
        code = 2 if result.errors else 0
    except StudyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        summary = {"error": str(exc)}
        code = 2
    except KeyboardInterrupt:
        print(
            "interrupted: finished settings and participants are kept; run the same command "
            "again to continue",
            file=sys.stderr,
        )
        summary = {"status": "interrupted"}
        code = 130
    print(json.dumps(summary))
    return code

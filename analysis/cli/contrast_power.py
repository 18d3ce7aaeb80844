"""``python -m analysis power --effect FACTOR | --pair A B``: power of declared contrasts.

The design (factors, within or between) is the protocol's kept with the pilot's data (or
``--protocol``); see :mod:`analysis.contrast_power`. Returns the power result and notes for
:mod:`analysis.cli.power` to write as it writes the paper's.
"""

from __future__ import annotations

import argparse

from analysis.contrast_power import Contrast, contrast_power, parse_condition, pilot_conditions
from analysis.errors import DesignError
from analysis.factor_design import condition_cells, factor_design
from analysis.load import StudyTables
from analysis.power import PowerResult
from analysis.protocol_info import DEFAULT_PROTOCOL, load_protocol_info


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="FACTOR",
        help="a declared factor whose main effect to power (repeatable); with --pair, "
        "replaces the paper's hypotheses",
    )
    parser.add_argument(
        "--pair",
        action="append",
        nargs=2,
        default=[],
        metavar=("A", "B"),
        help="two conditions to compare, each factor=level[,factor=level...] (unnamed within "
        "factors averaged), e.g. --pair mode=timid mode=aggressive (repeatable)",
    )
    parser.add_argument(
        "--dv", default="duration_s", help="the measure (a trials column; default duration_s)"
    )
    parser.add_argument(
        "--protocol",
        default=None,
        help="protocol TOML, read only when the pilot keeps none "
        f"(default {DEFAULT_PROTOCOL.name})",
    )


def wanted(args: argparse.Namespace) -> bool:
    """The user named contrasts (else the paper's hypotheses are powered)."""
    return bool(args.effect or args.pair)


def run(tables: StudyTables, args: argparse.Namespace) -> tuple[PowerResult, list[str]]:
    """The power of the named contrasts on the pilot ``tables``, and notes."""
    proto = load_protocol_info(
        args.protocol or DEFAULT_PROTOCOL, stored=tables.source, explicit=args.protocol is not None
    )
    design = factor_design(tables.trials, proto.factors, between=proto.between)
    if args.dv not in tables.trials.columns:
        raise DesignError(f"the trials table has no column {args.dv!r}; pass --dv a measure it has")
    cells, notes = condition_cells(tables.trials, design, successful_only=args.successful_only)
    contrasts = []
    for f in args.effect:
        if f not in design.factors:
            raise DesignError(
                f"{f!r} is not a factor that varies in this design ({', '.join(design.factors)})"
            )
        contrasts.append(Contrast(f"main effect of {f}", factor=f))
    for a, b in args.pair:
        ca, cb = parse_condition(a, design), parse_condition(b, design)
        contrasts.append(Contrast(f"{a} - {b}", a=ca, b=cb))
    pilot = pilot_conditions(cells, design, dv=args.dv)
    res = contrast_power(pilot, contrasts, ns=args.n, b=args.b, alpha=args.alpha, seed=args.seed)
    return res, [*proto.notes, *notes]

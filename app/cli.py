"""Subcommand dispatch shared by ``python -m study`` and ``python -m analysis``.

Each subcommand lives in its own module exposing ``add_arguments(parser)`` and
``main(args) -> int``; modules are imported only when their command runs, so ``--help`` stays
fast and one broken command never hides the others.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Mapping, Sequence


def dispatch(
    prog: str, description: str, commands: Mapping[str, tuple[str, str]], argv: Sequence[str] | None
) -> int:
    """Parse ``argv`` and run the chosen command.

    ``commands`` maps a command name to ``(module path, one-line help)``.
    """
    # the description is the package's module docstring: shown without its reST backticks
    parser = argparse.ArgumentParser(prog=prog, description=description.replace("``", ""))
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    args_list = list(sys.argv[1:] if argv is None else argv)
    chosen = next((a for a in args_list if not a.startswith("-")), None)
    for name, (module_path, help_text) in commands.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == chosen:
            importlib.import_module(module_path).add_arguments(p)
    args = parser.parse_args(args_list)
    module = importlib.import_module(commands[args.command][0])
    return int(module.main(args) or 0)


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0 (seeds, indices)."""
    value = _parse(text, int, "an integer")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer > 0 (counts, pixel sizes)."""
    value = _parse(text, int, "an integer")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be an integer > 0, got {text}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0 (rates, durations)."""
    value = _parse(text, float, "a number")
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0 (noise levels, margins)."""
    value = _parse(text, float, "a number")
    if not 0.0 <= value < float("inf"):  # False for NaN too
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def port(text: str) -> int:
    """argparse type: a TCP port, 0..65535 (0: any free port, which the server then prints)."""
    value = _parse(text, int, "a port number")
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(
            f"must be a TCP port from 1 to 65535 (or 0 for any free port), got {text}"
        )
    return value


def rate_hz(maximum: float) -> Callable[[str], float]:
    """argparse type factory: a rate in (0, ``maximum``] per second.

    A rate of 0 (or a negative or NaN one) would turn a period ``1 / rate`` into infinity or
    nonsense deep inside a loop (a scene that freezes at its first frame, say); refusing it at
    the command line names the flag instead."""

    def parse(text: str) -> float:
        value = _parse(text, float, "a number")
        if not 0.0 < value <= maximum:  # False for NaN too
            raise argparse.ArgumentTypeError(
                f"must be a rate above 0 and at most {maximum:g} per second, got {text}"
            )
        return value

    parse.__name__ = "rate"  # argparse names the type in "invalid rate value"
    return parse


def _parse(text: str, kind: type, what: str):  # type: ignore[no-untyped-def]
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None

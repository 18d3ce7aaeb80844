"""Subcommand dispatch shared by ``python -m study`` and ``python -m analysis``.

Each subcommand lives in its own module exposing ``add_arguments(parser)`` and
``main(args) -> int``; modules are imported only when their command runs, so ``--help`` stays
fast and one broken command never hides the others.

Every error a command line can cause is one line on stderr and exit code 2: argparse's own
(a bad value names the flag; no usage block) and the layer's error roots (``expected``: a
``StudyError`` from any study command, an ``AnalysisError`` from analysis), caught here once.
An exception nobody expected is one line too (exit 1; ``STUDY_TRACEBACK=1`` shows where it came
from), running out of memory is said as such, and Ctrl-C exits 130 without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import traceback
from collections.abc import Mapping, Sequence

from study.errors import StudyError


class UsageError(StudyError, ValueError):
    """Options that do not go together, or a value argparse cannot check alone (``--store``
    without ``--trial-id``); said like argparse's own errors, on one line."""


class OneLineParser(argparse.ArgumentParser):
    """argparse, with each error on one line (``prog: error: ... (see --help)``), exit 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def dispatch(
    prog: str,
    description: str,
    commands: Mapping[str, tuple[str, str]],
    argv: Sequence[str] | None,
    *,
    expected: tuple[type[BaseException], ...] = (),
) -> int:
    """Parse ``argv`` and run the chosen command.

    ``commands`` maps a command name to ``(module path, one-line help)``; an ``expected`` error
    (the layer's roots) is printed as ``prog command: error: message`` with exit code 2.
    """
    # the description is the package's module docstring: shown without its reST backticks
    parser = OneLineParser(prog=prog, description=description.replace("``", ""))
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    args_list = list(sys.argv[1:] if argv is None else argv)
    chosen = next((a for a in args_list if not a.startswith("-")), None)
    for name, (module_path, help_text) in commands.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == chosen:
            importlib.import_module(module_path).add_arguments(p)
    args = parser.parse_args(args_list)
    module = importlib.import_module(commands[args.command][0])
    try:
        return int(module.main(args) or 0)
    except KeyboardInterrupt:
        print(f"{prog} {args.command}: interrupted", file=sys.stderr)
        return 130
    except expected as exc:  # the command said no on purpose; its message says what to do
        print(f"{prog} {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except MemoryError:
        print(
            f"{prog} {args.command}: error: out of memory (the input asks for too much)",
            file=sys.stderr,
        )
        return 2
    except Exception as exc:  # a command's own errors are handled by it; this is a bug
        if os.environ.get("STUDY_TRACEBACK"):
            traceback.print_exc()
        print(
            f"{prog} {args.command}: unexpected error: {type(exc).__name__}: {_one_line(exc)[:300]}"
            " (a bug; STUDY_TRACEBACK=1 shows where)",
            file=sys.stderr,
        )
        return 1


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (a ``KeyError``'s without the quotes ``str`` adds)."""
    text = exc.args[0] if isinstance(exc, KeyError) and len(exc.args) == 1 else exc
    return " ".join(str(text).split())

"""``python -m study run``: one whole session headless, through the same engine as the server.

    python -m study run --protocol protocols/dragan2013.toml --db data/study.db \\
        --participant P01 --input scripted --seed 1 [--resume]

Items are answered by the scripted rule of ``study.session.answers``. Progress goes to stderr; the last
line on stdout is one JSON object: participant, trials_completed, ratings, status (plus
``error`` when the run could not go on: exit code 2 for bad input, a refused store or a disk
that is full or read-only, 1 for an unexpected failure, whose traceback goes to stderr; the
session is closed with its running trial marked interrupted either way -- or, if the disk took
no more writes, left for ``--resume`` to mark -- so ``--resume`` continues it).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from study.cli.arguments import int_range, seed
from study.errors import StudyError
from study.protocol import load_protocol
from study.protocol.preflight import check_scenes
from study.session import Session, TrialSummary, open_store
from study.session.answers import ScriptedAnswers
from study.session.headless import report as make_report
from study.session.headless import run_headless
from study.store import Store, StoreError

DEFAULT_PROTOCOL = Path(__file__).resolve().parents[2] / "protocols" / "dragan2013.toml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--protocol", type=Path, default=DEFAULT_PROTOCOL, help="protocol TOML")
    parser.add_argument("--db", type=Path, required=True, help="study store (SQLite file)")
    parser.add_argument("--participant", required=True, help="pseudonymous ID, e.g. P01")
    parser.add_argument("--input", choices=["scripted"], default="scripted", help="user input")
    parser.add_argument(
        "--seed",
        type=seed,
        default=0,
        help="session seed for a new session (trials, answers); a resumed one keeps its own",
    )
    parser.add_argument(
        "--resume", action="store_true", help="continue this participant's interrupted session"
    )
    parser.add_argument(
        "--demographics",
        type=_json_object,
        default=None,
        help="JSON object, stored apart from trial data, e.g. '{\"age\": 30}'"
        f" (at most {MAX_DEMOGRAPHICS} characters, nested at most {MAX_DEMOGRAPHICS_DEPTH} deep)",
    )
    parser.add_argument(
        "--schedule-row",
        type=int_range(0, MAX_SCHEDULE_ROW),
        default=None,
        help=f"override the design row, 0..{MAX_SCHEDULE_ROW} (rows repeat every cycle)",
    )
    parser.add_argument("--realtime", action="store_true", help="pace trials to wall-clock time")
    parser.add_argument(
        "--synchronous", choices=["FULL", "NORMAL"], default="FULL", help="SQLite durability"
    )


MAX_DEMOGRAPHICS = 4096
MAX_DEMOGRAPHICS_DEPTH = 4
MAX_SCHEDULE_ROW = 99_999


def _json_object(text: str) -> dict[str, Any]:
    if len(text) > MAX_DEMOGRAPHICS:
        raise argparse.ArgumentTypeError(
            f"{len(text)} characters; at most {MAX_DEMOGRAPHICS} (a few answers, not a file)"
        )
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not JSON ({exc}); e.g. '{{\"age\": 30}}'") from None
    except RecursionError:
        raise argparse.ArgumentTypeError("nested too deeply to read") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"must be a JSON object, got {type(value).__name__}")
    if _depth(value) > MAX_DEMOGRAPHICS_DEPTH:
        raise argparse.ArgumentTypeError(f"nested more than {MAX_DEMOGRAPHICS_DEPTH} levels deep")
    return value


def _depth(value: Any) -> int:
    if isinstance(value, dict):
        return 1 + max(map(_depth, value.values()), default=0)
    if isinstance(value, list):
        return 1 + max(map(_depth, value), default=0)
    return 0


@dataclass
class _Opened:
    """What ``main`` opened, to close whatever happens."""

    store: Store | None = None
    session: Session | None = None


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(args: argparse.Namespace) -> int:
    result: dict[str, Any] = {"participant": args.participant}
    opened = _Opened()
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    code = 1
    try:
        session = _open(args, opened)
        report = run_headless(
            session,
            answerer=ScriptedAnswers(seed=session.seed),
            realtime=args.realtime,
            on_trial=_trial_logger(args.participant),
        )
        result = report.as_dict()
        code = 0
    except StudyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        result.update(status="error", error=str(exc))
        code = 2
    except KeyboardInterrupt:
        print("interrupted: the running trial is marked interrupted; use --resume", file=sys.stderr)
        result.update(status="interrupted")
        code = 130
    except Exception as exc:  # a bug: keep the data, say how to go on, show the traceback
        traceback.print_exc()
        print(
            "error: unexpected failure (traceback above); recorded data are kept and the running "
            "trial is marked interrupted: fix the cause, then continue with --resume",
            file=sys.stderr,
        )
        result.update(status="error", error=f"{type(exc).__name__}: {exc}")
        code = 1
    finally:
        signal.signal(signal.SIGTERM, previous)
        result, code = _close(opened, result, code)
    print(json.dumps(result))
    return code


def _open(args: argparse.Namespace, opened: _Opened) -> Session:
    """Load and check the protocol, open the store, enrol (or reopen) the participant."""
    protocol = load_protocol(args.protocol)
    check_scenes(protocol)  # every scene builds, before anything is written
    if args.resume and not args.db.is_file():
        # opening would create an empty store as a side effect of a mistyped path
        raise StoreError(f"no store at {args.db}; --resume needs the store the session started in")
    opened.store = open_store(args.db, protocol, synchronous=args.synchronous)
    if args.resume:
        opened.session = Session.reopen(opened.store, protocol, args.participant)
    else:
        opened.session = Session.enrol(
            opened.store,
            protocol,
            args.participant,
            seed=args.seed,
            demographics=args.demographics,
            schedule_row=args.schedule_row,
        )
    return opened.session


def _trial_logger(participant: str) -> Callable[[TrialSummary | None], None]:
    """One line on stderr per finished trial."""

    def log(summary: TrialSummary | None) -> None:
        if summary is None:
            print(f"{participant}: trial aborted", file=sys.stderr)
            return
        print(
            f"{participant}: trial {summary.trial_id}: {summary.outcome} after "
            f"{summary.duration_s:.2f} s ({summary.ticks} ticks)",
            file=sys.stderr,
        )

    return log


def _close(opened: _Opened, result: dict[str, Any], code: int) -> tuple[dict[str, Any], int]:
    """Close the session and the store; the result gains the session's report if the run did
    not finish, and the error if closing could not record itself (a full or read-only disk)."""
    session = opened.session
    if session is not None:
        if "trials_completed" not in result:
            result = {**make_report(session).as_dict(), **result}
            result.setdefault("status", session.status)
        try:
            session.close()
        except StoreError as exc:  # a full or read-only disk: closed, but not recorded
            if str(exc) != result.get("error"):
                print(f"error: {exc}", file=sys.stderr)
            result.setdefault("error", str(exc))
            result["status"] = "error"
            code = code or 2
    if opened.store is not None:
        opened.store.close()
    return result, code

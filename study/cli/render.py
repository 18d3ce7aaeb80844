"""``python -m study render``: film a trial to MP4, live or replayed from saved records.

Live: ``python -m study render --task hard-right --mode aggressive --seed 1`` (writes
``data/videos/trial.mp4`` unless ``--out`` says otherwise).
Replay: ``python -m study trial ... --save run.npz`` then
``python -m study render --replay run.npz --task hard-right`` (the task names the scene), or from
a study store: ``--store data/study.db --trial-id 12`` (the scene comes from the protocol the
store keeps, or ``--protocol`` for older stores).

Standard output is one JSON line; progress and errors go to standard error. Rendering is
headless (``MUJOCO_GL=egl`` by default).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

from app.files import InputFileError, check_input_file
from app.robot.scene import build_scene
from app.trial import load_records, records_from_samples
from app.trial.video import render_live, replay
from study.cli.arguments import float_range, int_range, output_file, seed
from study.cli.dispatch import UsageError
from study.cli.trial import DEFAULT_PROTOCOL, INPUTS, make_input
from study.protocol import ProtocolError, protocol_from_store, trial_config_from_protocol
from study.store import Store, StoreError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", default="hard-right", help="task name, or 'training'")
    parser.add_argument("--mode", default="timid", help="mode name, or 'none' (unassisted)")
    parser.add_argument("--input", choices=INPUTS, default="scripted")
    parser.add_argument("--seed", type=seed, default=0, help="seed of the scripted user (live)")
    parser.add_argument("--protocol", type=Path, default=DEFAULT_PROTOCOL, help="protocol TOML")
    parser.add_argument("--replay", type=Path, default=None, help="records (.npz) to replay")
    parser.add_argument("--store", type=Path, default=None, help="study store (SQLite) to replay")
    parser.add_argument("--trial-id", type=seed, default=None, help="trial to replay from --store")
    parser.add_argument(
        "--out", type=output_file, default=Path("data/videos/trial.mp4"), help="MP4 to write"
    )
    parser.add_argument(
        "--fps", type=float_range(0.0, 240.0, above=True), default=30.0, help="frames a second"
    )
    parser.add_argument("--width", type=int_range(16, 4096), default=640, help="pixels, 16..4096")
    parser.add_argument("--height", type=int_range(16, 4096), default=480, help="pixels, 16..4096")
    parser.add_argument(
        "--time-limit",
        type=float_range(0.0, 3600.0, above=True),
        default=None,
        help="override, seconds (live), in (0, 3600]",
    )


def _stored_config(store: Any, task: str, fallback: Path) -> Any:
    """The scene the trial ran in: from the protocol the store keeps, else ``fallback``."""
    try:
        protocol = protocol_from_store(store)
    except ProtocolError:  # an older store without the protocol's text
        return trial_config_from_protocol(fallback, task, "none")
    return protocol.config_for(task, "none")


MAX_RECORDS_BYTES = 512 * 2**20
"""Largest records file replayed (an hour of 100 Hz ticks is about 60 MB)."""


def _records(path: Path) -> tuple[dict[str, Any], Any]:
    """What ``trial --save`` wrote at ``path`` (a regular file of bounded size), else
    ``InputFileError`` naming the file."""
    check_input_file(path, max_bytes=MAX_RECORDS_BYTES, what="records file")
    try:
        return load_records(path)
    except Exception as exc:  # numpy and zipfile raise many kinds for a file of another kind
        raise InputFileError(
            "records file",
            path,
            f"is not one written by `python -m study trial --save` ({type(exc).__name__})",
        ) from None


def main(args: argparse.Namespace) -> int:
    try:
        config = trial_config_from_protocol(
            args.protocol, args.task, args.mode, time_limit_s=args.time_limit
        )
        size = {"fps": args.fps, "width": args.width, "height": args.height}
        build_scene(config.scene)  # reachable and compiling, before anything is written
        if args.store is not None:
            if args.trial_id is None:
                raise UsageError("--store needs --trial-id")
            store = Store.open_readonly(args.store)
            row = store.trial(args.trial_id)
            task = row.task if row.phase != "training" and row.task else "training"
            config = _stored_config(store, task, args.protocol)
            records = records_from_samples(store.samples(args.trial_id))
            if not records:
                raise StoreError(f"trial {args.trial_id} has no samples in {args.store}")
            frames = replay(
                build_scene(config.scene), records, args.out, rate_hz=config.rate_hz, **size
            )
            summary = {"store": str(args.store), "trial_id": args.trial_id, "outcome": row.outcome}
        elif args.replay is not None:
            meta, records = _records(args.replay)
            frames = replay(
                build_scene(config.scene), records, args.out, rate_hz=config.rate_hz, **size
            )
            summary = {"replay": str(args.replay), "outcome": meta.get("outcome")}
        else:
            source = make_input(args.input, seed=args.seed, speed=0.15, noise=0.002)
            result, frames = render_live(config, source, args.out, seed=args.seed, **size)
            summary = result.summary()
    except OSError as exc:  # a file the options name (Study/AppErrors: said by the dispatcher)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary.update(video=str(args.out), frames=frames)
    print(f"wrote {frames} frames to {args.out}", file=sys.stderr)
    print(json.dumps(summary))
    return 0

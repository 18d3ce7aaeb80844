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

from app.cli import non_negative_int, positive_float, positive_int
from app.robot.scene import build_scene
from app.trial import load_records, records_from_samples
from app.trial.video import render_live, replay
from study.cli.trial import DEFAULT_PROTOCOL, INPUTS, make_input
from study.protocol import protocol_from_store, trial_config_from_protocol
from study.store import Store


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", default="hard-right", help="task name, or 'training'")
    parser.add_argument("--mode", default="timid", help="mode name, or 'none' (unassisted)")
    parser.add_argument("--input", choices=INPUTS, default="scripted")
    parser.add_argument(
        "--seed", type=non_negative_int, default=0, help="seed of the scripted user (live)"
    )
    parser.add_argument("--protocol", type=Path, default=DEFAULT_PROTOCOL, help="protocol TOML")
    parser.add_argument("--replay", type=Path, default=None, help="records (.npz) to replay")
    parser.add_argument("--store", type=Path, default=None, help="study store (SQLite) to replay")
    parser.add_argument(
        "--trial-id", type=non_negative_int, default=None, help="trial to replay from --store"
    )
    parser.add_argument(
        "--out", type=Path, default=Path("data/videos/trial.mp4"), help="MP4 to write"
    )
    parser.add_argument("--fps", type=positive_float, default=30.0, help="frames per second")
    parser.add_argument("--width", type=positive_int, default=640, help="pixels")
    parser.add_argument("--height", type=positive_int, default=480, help="pixels")
    parser.add_argument(
        "--time-limit", type=positive_float, default=None, help="override, seconds (live)"
    )


def _stored_config(store: Any, task: str, fallback: Path) -> Any:
    """The scene the trial ran in: from the protocol the store keeps, else ``fallback``."""
    try:
        protocol = protocol_from_store(store)
    except ValueError:  # an older store without the protocol's text
        return trial_config_from_protocol(fallback, task, "none")
    return protocol.config_for(task, "none")


def main(args: argparse.Namespace) -> int:
    try:
        config = trial_config_from_protocol(
            args.protocol, args.task, args.mode, time_limit_s=args.time_limit
        )
        size = {"fps": args.fps, "width": args.width, "height": args.height}
        if args.store is not None:
            if args.trial_id is None:
                raise ValueError("--store needs --trial-id")
            store = Store.open_readonly(args.store)
            row = store.trial(args.trial_id)
            task = row.task if row.phase != "training" and row.task else "training"
            config = _stored_config(store, task, args.protocol)
            records = records_from_samples(store.samples(args.trial_id))
            if not records:
                raise ValueError(f"trial {args.trial_id} has no samples in {args.store}")
            frames = replay(
                build_scene(config.scene), records, args.out, rate_hz=config.rate_hz, **size
            )
            summary = {"store": str(args.store), "trial_id": args.trial_id, "outcome": row.outcome}
        elif args.replay is not None:
            meta, records = load_records(args.replay)
            frames = replay(
                build_scene(config.scene), records, args.out, rate_hz=config.rate_hz, **size
            )
            summary = {"replay": str(args.replay), "outcome": meta.get("outcome")}
        else:
            source = make_input(args.input, seed=args.seed, speed=0.15, noise=0.002)
            result, frames = render_live(config, source, args.out, seed=args.seed, **size)
            summary = result.summary()
    except (ValueError, KeyError, OSError, RuntimeError) as exc:  # incl. VideoError, StoreError
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary.update(video=str(args.out), frames=frames)
    print(f"wrote {frames} frames to {args.out}", file=sys.stderr)
    print(json.dumps(summary))
    return 0

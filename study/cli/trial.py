"""``python -m study trial``: run one headless trial and print its outcome; last line is JSON.

Example: ``python -m study trial --task hard-right --mode aggressive --input scripted --seed 1``.
``--mode none`` runs the task unassisted (alpha = 0); ``--task training`` runs the training
scene. The configuration comes from the protocol (``--protocol``, default
``protocols/dragan2013.toml``) through ``study.protocol.load_protocol``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from app.robot import build_scene
from app.teleop import IdleInput, InputSource, ScriptedInput
from app.trial import save_records
from app.trial.trial import run_trial
from study.cli.arguments import float_range, output_file, seed
from study.cli.dispatch import UsageError
from study.protocol import trial_config_from_protocol

DEFAULT_PROTOCOL = Path(__file__).resolve().parents[2] / "protocols" / "dragan2013.toml"
INPUTS = ("scripted", "idle")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", default="hard-right", help="task name, or 'training'")
    parser.add_argument("--mode", default="timid", help="mode name, or 'none' (unassisted)")
    parser.add_argument("--input", choices=INPUTS, default="scripted", help="input source")
    parser.add_argument("--seed", type=seed, default=0, help="seed of the scripted user")
    parser.add_argument("--protocol", type=Path, default=DEFAULT_PROTOCOL, help="protocol TOML")
    parser.add_argument("--realtime", action="store_true", help="pace to wall-clock time")
    parser.add_argument(
        "--speed",
        type=float_range(0.0, 2.0, above=True),
        default=0.15,
        help="scripted user speed, m/s, in (0, 2]",
    )
    parser.add_argument(
        "--noise", type=float_range(0.0, 0.1), default=0.002, help="scripted user noise, m, 0..0.1"
    )
    parser.add_argument(
        "--time-limit",
        type=float_range(0.0, 3600.0, above=True),
        default=None,
        help="override, s, in (0, 3600]",
    )
    parser.add_argument("--save", type=output_file, default=None, help="write the records (.npz)")


def make_input(name: str, *, seed: int, speed: float, noise: float) -> InputSource:
    if name == "scripted":
        return ScriptedInput(seed=seed, speed=speed, noise=noise)
    if name == "idle":
        return IdleInput()
    raise UsageError(f"--input: one of {INPUTS}, got {name!r}")


def main(args: argparse.Namespace) -> int:
    try:
        config = trial_config_from_protocol(
            args.protocol, args.task, args.mode, time_limit_s=args.time_limit
        )
        source = make_input(args.input, seed=args.seed, speed=args.speed, noise=args.noise)
        build_scene(config.scene)  # reachable and compiling, before the trial starts
    except OSError as exc:  # a file the options name (Study/AppErrors: said by the dispatcher)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    wall = time.perf_counter()
    result = run_trial(config, source, seed=args.seed, realtime=args.realtime)
    wall = time.perf_counter() - wall
    summary = result.summary()
    summary.update(task=args.task, mode=args.mode, input=args.input, wall_s=round(wall, 3))
    print(
        f"{args.task} / {args.mode} / {args.input} seed {args.seed}: {result.outcome}"
        f" after {result.duration_s:.2f} s ({result.ticks} ticks, {wall:.2f} s wall)",
        file=sys.stderr,
    )
    if args.save is not None:
        try:
            print(f"records written to {save_records(result, args.save)}", file=sys.stderr)
        except OSError as exc:
            print(f"error: cannot write {args.save}: {exc.strerror or exc}", file=sys.stderr)
            return 2
    print(json.dumps(summary))
    return 0

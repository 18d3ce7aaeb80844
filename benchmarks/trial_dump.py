"""Dump every tick record of 24 headless trials, bit for bit, to compare two versions of the code.

The trials: the protocol's 12 tasks x modes (``dragan2013.toml``), 2 seeds each (a scripted
user, ``ScriptedInput(seed)``), full time limits. Each tick record is written as one line: every
field in ``TickRecord`` order, arrays as their dtype and raw bytes (hex), floats as
``float.hex``, events as their stored text; then the trial's events and outcome. A change to the
control tick that should not change what a study stores leaves the dump byte-identical::

    python benchmarks/trial_dump.py --out /tmp/after.txt      # on this tree
    (cd <other tree> && python benchmarks/trial_dump.py --out /tmp/before.txt)
    cmp /tmp/before.txt /tmp/after.txt

Prints the number of ticks and the dump's SHA-256 as one JSON line. Bit-equality holds on one
machine (the same MuJoCo, BLAS and CPU); another machine may round differently in both trees.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.teleop import ScriptedInput  # noqa: E402
from app.trial import TickRecord, run_trial  # noqa: E402
from app.trial.events import encode  # noqa: E402
from study.protocol import trial_config_from_protocol  # noqa: E402

PROTOCOL = ROOT / "protocols" / "dragan2013.toml"
TASKS = ("easy-right", "easy-wrong", "hard-right", "hard-wrong")
MODES = ("none", "timid", "aggressive")
SEEDS = (0, 1)


def _exact(value: Any) -> str:
    """``value`` written so that equal text means equal bits (and equal types)."""
    if isinstance(value, np.ndarray):
        return f"{value.dtype.str}{value.shape}:{value.tobytes().hex()}"
    if isinstance(value, float):
        return f"f:{value.hex()}"
    if isinstance(value, tuple):  # events
        return "[" + ",".join(encode(e) for e in value) + "]"
    return f"{type(value).__name__}:{value!r}"


def record_line(record: TickRecord) -> str:
    """One tick record, every field in order."""
    return " ".join(_exact(getattr(record, name)) for name in record.__slots__)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="the dump file to write")
    args = parser.parse_args()
    digest = hashlib.sha256()
    ticks = 0
    with args.out.open("w") as out:
        for task in TASKS:
            for mode in MODES:
                config = trial_config_from_protocol(PROTOCOL, task, mode)
                for seed in SEEDS:
                    result = run_trial(config, ScriptedInput(seed=seed), seed=seed)
                    lines = [f"trial {task} {mode} {seed} {result.outcome} {result.ticks}"]
                    lines += [record_line(r) for r in result.records]
                    lines += [f"event f:{t.hex()} {encode(e)}" for t, e in result.events]
                    text = "\n".join(lines) + "\n"
                    out.write(text)
                    digest.update(text.encode())
                    ticks += len(result.records)
    print(
        json.dumps(
            {
                "trials": len(TASKS) * len(MODES) * len(SEEDS),
                "ticks": ticks,
                "sha256": digest.hexdigest(),
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

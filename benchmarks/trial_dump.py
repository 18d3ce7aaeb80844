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

A change meant to move the numbers by rounding only (the fused control step,
``app.trial.fused_control``) is compared column by column instead::

    python benchmarks/trial_dump.py --diff /tmp/before.txt /tmp/after.txt

which prints, as one JSON line, whether every trial's outcome, tick count and events are the
same, and the largest absolute difference of every logged column over every tick.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
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


def _value(text: str) -> Any:
    """A field of a dump line back as numbers (``_exact``'s inverse for arrays, floats, ints)."""
    if text.startswith("<f8"):
        return np.frombuffer(bytes.fromhex(text.split(":", 1)[1]), dtype="<f8")
    if text.startswith("f:"):
        return float.fromhex(text[2:])
    if text.startswith("int:"):
        return int(text[4:])
    return text


def _trials(path: Path) -> dict[str, dict[str, Any]]:
    """A dump's trials: their header, tick lines (fields split) and event lines."""
    out: dict[str, dict[str, Any]] = {}
    current: dict[str, Any] = {}
    for line in path.read_text().splitlines():
        if line.startswith("trial "):
            current = out[line.rsplit(" ", 2)[0]] = {"head": line, "rows": [], "events": []}
        elif line.startswith("event "):
            current["events"].append(line)
        else:
            current["rows"].append(line.split(" "))
    return out


def diff(before: Path, after: Path) -> dict[str, Any]:
    """Per logged column, the largest absolute difference over every tick of every trial (the
    trials paired by task, mode and seed); and whether outcomes, tick counts and events match."""
    a, b = _trials(before), _trials(after)
    names = [n for n in TickRecord.__slots__ if n != "events"]
    worst = dict.fromkeys(names, 0.0)
    same = {"outcomes_and_ticks": a.keys() == b.keys(), "events": True, "tick_events": True}
    for key in a.keys() & b.keys():
        same["outcomes_and_ticks"] &= a[key]["head"] == b[key]["head"]
        same["events"] &= a[key]["events"] == b[key]["events"]
        for row_a, row_b in zip(a[key]["rows"], b[key]["rows"], strict=False):
            for name, x, y in zip(TickRecord.__slots__, row_a, row_b, strict=True):
                if x == y:
                    continue
                if name == "events":
                    same["tick_events"] = False
                    continue
                d = np.abs(np.asarray(_value(x), float) - np.asarray(_value(y), float)).max()
                worst[name] = max(worst[name], float(d) if d == d else math.inf)
    return {"same": same, "max_abs_difference": worst}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, help="the dump file to write")
    parser.add_argument(
        "--diff", type=Path, nargs=2, metavar=("BEFORE", "AFTER"), help="compare two dumps"
    )
    args = parser.parse_args()
    if args.diff:
        print(json.dumps(diff(*args.diff)))
        return 0
    if args.out is None:
        parser.error("give --out FILE (or --diff BEFORE AFTER)")
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

"""argparse types shared by ``python -m study`` and ``python -m analysis``: every number gets a
range and every path a kind (a file to read, a file or a folder to write), so a bad value is
refused at the command line with the flag's name, before anything runs.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Callable
from pathlib import Path

MAX_SEED = 2**63 - 1
"""Largest seed a store keeps (SQLite integers are 64-bit)."""


def int_range(lo: int, hi: int, *, what: str = "a whole number") -> Callable[[str], int]:
    """argparse type factory: an integer in [lo, hi]."""

    def parse(text: str) -> int:
        value = _parse(text, int, what)
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be {lo}..{hi}, got {text}")
        return value

    parse.__name__ = "int"
    return parse


def float_range(lo: float, hi: float, *, above: bool = False) -> Callable[[str], float]:
    """argparse type factory: a finite number in [lo, hi] (``above``: in (lo, hi])."""

    def parse(text: str) -> float:
        value = _parse(text, float, "a number")
        low_ok = value > lo if above else value >= lo
        if not (math.isfinite(value) and low_ok and value <= hi):
            bracket = "(" if above else "["
            raise argparse.ArgumentTypeError(f"must be in {bracket}{lo:g}, {hi:g}], got {text}")
        return value

    parse.__name__ = "number"
    return parse


def seed(text: str) -> int:
    """argparse type: a seed, 0..2**63-1."""
    value = _parse(text, int, "a whole number")
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be a whole number 0..{MAX_SEED}, got {text}")
    return value


def output_file(text: str) -> Path:
    """argparse type: a file to write: not a folder, in a folder that exists and is writable."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder; name a file to write")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(f"the folder {folder} does not exist")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise argparse.ArgumentTypeError(f"{text} cannot be written (permission denied)")
    return path


def output_dir(text: str) -> Path:
    """argparse type: a folder to write into (created if missing): not an existing file, under
    a writable folder."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, not a folder; name a folder")
    existing = next((p for p in (path, *path.parents) if p.exists()), Path("."))
    if not existing.is_dir() or not os.access(existing, os.W_OK):
        raise argparse.ArgumentTypeError(f"{text} cannot be written under {existing}")
    return path


_SCHEDULER = re.compile(
    r"^((tcp|tls|ucx|ws|wss)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9][A-Za-z0-9.-]*):\d{1,5}$"
)


def scheduler_address(text: str) -> str:
    """argparse type: a Dask scheduler's address, ``[tcp://]HOST:PORT``."""
    match = _SCHEDULER.match(text)
    if match is None or not 0 < int(text.rsplit(":", 1)[1]) <= 65535:
        raise argparse.ArgumentTypeError(
            f"must be a scheduler address such as tcp://10.0.0.5:8786, got {text!r}"
        )
    return text


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

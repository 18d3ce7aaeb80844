"""The grid of arbitration settings a sweep tries, and the protocol variant for each.

The paper (section 4) fixes two arbitration modes by two criteria (``study.sweep.criteria``):
*timid* (``alpha = alpha_max * min(1, c / saturation)``) is swept over ``alpha_max`` with
the protocol's ``saturation``; *aggressive* (``alpha = alpha_high`` once ``c >= threshold``,
else 0) over ``threshold`` x ``alpha_high``. One setting changes one mode only: every other
line of the protocol, the other mode included, stays as written, so the two searches do not
mix. A sweep of the distance confidence's ``D`` (``c = max(0, 1 - d / D)``, section 3.2) runs
the protocol's own two modes at each ``D``: one setting per mode, both in one store, judged by
the same criteria but never picked (help, the area under ``alpha(c)``, does not compare
settings with different ``D``).

A variant is the protocol's own TOML text with that mode's ``arbitration = { ... }`` line
replaced (the protocol format keeps it on one line, an inline table), and for a ``D`` setting
the ``D = ...`` line of ``[confidence]`` too, loaded and validated like any protocol; each
variant runs into its own store.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from study.sweep.errors import SweepGridError, SweepProtocolError

TIMID = "timid"
AGGRESSIVE = "aggressive"

DEFAULT_TIMID_ALPHA_MAX = (0.2, 0.3, 0.4, 0.5, 0.6)
DEFAULT_AGGRESSIVE_THRESHOLD = (0.2, 0.4, 0.6)
DEFAULT_AGGRESSIVE_ALPHA_HIGH = (0.7, 0.9, 1.0)
"""The default grid: 5 timid + 9 aggressive settings, today's dragan2013 values among them;
with 8 participants a setting that is 112 simulated sessions, a few minutes on 2 cores."""


@dataclass(frozen=True)
class Setting:
    """One mode's arbitration parameters (``params`` as in the protocol's inline table)."""

    mode: str
    params: tuple[tuple[str, float], ...]
    D: float | None = None
    """The distance confidence's ``D`` the mode runs with; ``None``: the protocol's own."""

    @property
    def label(self) -> str:
        text = f"{self.mode} " + " ".join(f"{k}={v:g}" for k, v in self.params)
        return text if self.D is None else f"{text} D={self.D:g}"

    @property
    def slug(self) -> str:
        text = f"{self.mode}-" + "-".join(f"{k}{v:g}" for k, v in self.params)
        return text if self.D is None else f"{text}-D{self.D:g}"

    def at(self, D: float) -> Setting:
        """The same arbitration under the distance confidence ``c = max(0, 1 - d / D)``."""
        return Setting(self.mode, self.params, float(D))

    def value(self, key: str) -> float:
        return dict(self.params)[key]

    def help(self, *, saturation: float) -> float:
        """How much help the setting gives, as one number: the area under its arbitration curve,
        ``integral_0^1 alpha(c) dc`` (timid ``alpha_max (1 - saturation / 2)``, aggressive
        ``alpha_high (1 - threshold)``). Parameter-only, so it orders settings without noise."""
        if self.mode == TIMID:
            return self.value("alpha_max") * (1 - saturation / 2)
        return self.value("alpha_high") * (1 - self.value("threshold"))

    def inline_table(self, *, saturation: float) -> str:
        extra = {"saturation": saturation} if self.mode == TIMID else {}
        fields = {"kind": self.mode, **dict(self.params), **extra}
        body = ", ".join(
            f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v:g}" for k, v in fields.items()
        )
        return "{ " + body + " }"


def timid(alpha_max: float) -> Setting:
    return Setting(TIMID, (("alpha_max", float(alpha_max)),))


def aggressive(threshold: float, alpha_high: float) -> Setting:
    return Setting(AGGRESSIVE, (("threshold", float(threshold)), ("alpha_high", float(alpha_high))))


def make_grid(
    *,
    timid_alpha_max: tuple[float, ...] = DEFAULT_TIMID_ALPHA_MAX,
    aggressive_threshold: tuple[float, ...] = DEFAULT_AGGRESSIVE_THRESHOLD,
    aggressive_alpha_high: tuple[float, ...] = DEFAULT_AGGRESSIVE_ALPHA_HIGH,
) -> list[Setting]:
    """Every timid setting, then every aggressive one (threshold-major); values are checked
    against the arbitration's own ranges here, before anything runs."""
    for name, values, ok in (
        ("timid alpha_max", timid_alpha_max, lambda v: 0 < v < 1),
        ("aggressive threshold", aggressive_threshold, lambda v: 0 <= v <= 1),
        ("aggressive alpha_high", aggressive_alpha_high, lambda v: 0 < v <= 1),
    ):
        if not values:
            raise SweepGridError(f"{name}: give at least one value")
        bad = [v for v in values if not ok(v)]
        if bad:
            raise SweepGridError(
                f"{name}: {bad[0]:g} is out of range (timid alpha_max in (0, 1), aggressive "
                "threshold in [0, 1], alpha_high in (0, 1])"
            )
    return [timid(a) for a in sorted(set(timid_alpha_max))] + [
        aggressive(t, h)
        for t in sorted(set(aggressive_threshold))
        for h in sorted(set(aggressive_alpha_high))
    ]


def current_settings(text: str) -> tuple[Setting, Setting, float]:
    """The protocol's own timid and aggressive settings and the timid ``saturation``."""
    modes = tomllib.loads(text).get("modes", {})
    try:
        t = modes[TIMID]["arbitration"]
        a = modes[AGGRESSIVE]["arbitration"]
        current_timid = timid(t["alpha_max"])
        current_aggressive = aggressive(a["threshold"], a.get("alpha_high", 1.0))
        saturation = float(t.get("saturation", 1.0))
    except (KeyError, TypeError) as exc:
        raise SweepProtocolError(
            f'the protocol needs [modes.{TIMID}] arbitration = {{ kind = "timid", alpha_max = '
            f'... }} and [modes.{AGGRESSIVE}] arbitration = {{ kind = "aggressive", threshold '
            f"= ..., alpha_high = ... }} to be swept (missing {exc})"
        ) from None
    if t.get("kind") != TIMID or a.get("kind") != AGGRESSIVE:
        raise SweepProtocolError(
            "the sweep applies the paper's criteria to a timid and an aggressive arbitration: "
            f'[modes.{TIMID}] must have kind "timid" and [modes.{AGGRESSIVE}] kind "aggressive"'
        )
    return current_timid, current_aggressive, saturation


def check_D(values: tuple[float, ...]) -> tuple[float, ...]:
    """The ``D`` values of a sweep, sorted and unique; each must be positive (metres)."""
    bad = [v for v in values if not v > 0]
    if bad:
        raise SweepGridError(f"confidence D: {bad[0]:g} is out of range (D > 0, in metres)")
    return tuple(sorted(set(values)))


def protocol_D(text: str) -> float:
    """The protocol's distance-confidence ``D`` (``[confidence] kind = "distance"``)."""
    conf = tomllib.loads(text).get("confidence", {})
    if not isinstance(conf, dict) or conf.get("kind") != "distance" or "D" not in conf:
        raise SweepProtocolError(
            'a sweep of D needs [confidence] kind = "distance" with D = ... in the protocol'
        )
    return float(conf["D"])


def variant_text(text: str, setting: Setting, *, saturation: float) -> str:
    """``text`` with ``[modes.<mode>]``'s arbitration line replaced by ``setting`` (and
    ``[confidence]``'s ``D`` line by ``setting.D``, when it has one)."""
    if setting.D is not None:
        protocol_D(text)
        d_line = re.compile(r"(?m)^(\[confidence\][^\n]*\n(?:(?!\[)[^\n]*\n)*?D\s*=\s*)[^\s#]+")
        text, n = d_line.subn(lambda m: m.group(1) + f"{setting.D:g}", text, count=1)
        if n != 1:
            raise SweepProtocolError(
                "cannot find `D = ...` on its own line under [confidence]; write it so to sweep D"
            )
    pattern = re.compile(
        rf"(?ms)^(\[modes\.{re.escape(setting.mode)}\][^\[]*?^arbitration\s*=\s*)\{{[^\n]*\}}"
    )
    new, n = pattern.subn(
        lambda m: m.group(1) + setting.inline_table(saturation=saturation), text, count=1
    )
    if n != 1:
        raise SweepProtocolError(
            f"cannot find `arbitration = {{ ... }}` on one line under [modes.{setting.mode}]; "
            "write the mode's arbitration as an inline table on one line to sweep it"
        )
    return new


def write_variant(text: str, setting: Setting, *, saturation: float, folder: Path) -> Path:
    """Write the variant protocol for ``setting`` into ``folder``; returns its path."""
    path = folder / f"protocol-{setting.slug}.toml"
    path.write_text(variant_text(text, setting, saturation=saturation), encoding="utf-8")
    return path


def as_dict(setting: Setting) -> dict[str, Any]:
    return {"mode": setting.mode, **dict(setting.params)}

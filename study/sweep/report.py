"""What a sweep leaves behind: a table, a figure, the evidence, and the chosen parameters as a
protocol snippet.

Files in the sweep's folder:

- ``sweep.csv``: one row per setting (its parameters, ``D`` when swept (empty: the protocol's), help, participants, judged trials, rate,
  time lost, passes);
- ``sweep.json``: the same rows with the criteria, the seed and participants, the picks and
  the verdict on the protocol's current values;
- ``chosen.toml``: ``[modes.timid]`` / ``[modes.aggressive]`` arbitration lines to paste into a
  protocol, with the evidence as comments (a mode no setting passed for keeps a comment saying
  so, and no line);
- ``sweep.png``: timid hard-task completion against help, aggressive wrong-trial completion
  against help, thresholds drawn, today's values and the picks marked.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from study.sweep.criteria import Measure
from study.sweep.grid import AGGRESSIVE, TIMID
from study.sweep.run import SweepResult

COLUMNS = (
    "mode",
    "alpha_max",
    "threshold",
    "alpha_high",
    "D",
    "help",
    "participants",
    "trials",
    "rate",
    "time_lost_s",
    "passes",
)


def rows(result: SweepResult) -> list[dict[str, Any]]:
    return [{c: m.row().get(c) for c in COLUMNS} for m in result.measures]


def table(result: SweepResult) -> str:
    """The evidence as a fixed-width table; ``*`` marks the protocol's current settings, ``>``
    the picks."""
    head = (
        f"  {'mode':<10} {'alpha_max':>9} {'threshold':>9} {'alpha_high':>10} {'D':>5} {'help':>6} "
        f"{'trials':>6} {'rate':>6} {'lost_s':>7}  passes"
    )
    lines = [head]
    for m in result.measures:
        r = m.row()
        mark = ">" if result.chosen.get(m.setting.mode) == m else " "
        mark += "*" if result.current[m.setting.mode] == m.setting else " "
        lines.append(
            f"{mark}{r['mode']:<10} {_f(r.get('alpha_max')):>9} {_f(r.get('threshold')):>9} "
            f"{_f(r.get('alpha_high')):>10} {_f(r.get('D')):>5} {r['help']:>6.3f} {r['trials']:>6} "
            f"{r['rate']:>6.2f} {_f(r['time_lost_s']):>7}  {'yes' if r['passes'] else 'no'}"
        )
    c = result.criteria
    lines.append(
        f"rate: timid = hard-task completion (pass >= {c.min_hard_completion:g}); aggressive = "
        f"wrong trials completed (pass >= {c.min_wrong_corrected:g}, lost_s <= "
        f"{c.max_time_lost_s:g}); help = area under alpha(c); D: the confidence's (- the "
        "protocol's; never chosen); * today's, > chosen"
    )
    return "\n".join(lines)


def _f(v: Any) -> str:
    return "-" if v is None else f"{v:g}"


def snippet(result: SweepResult) -> str:
    """The chosen settings as protocol TOML, with the evidence as comments."""
    c = result.criteria
    out = [
        "# Arbitration chosen by `python -m study sweep` (Dragan & Srinivasa 2013, section 4):",
        f"# {result.participants} simulated participants per setting, seed {result.seed}, "
        f"protocol {Path(result.protocol).name}.",
        f"# timid: least help with hard-task completion >= {c.min_hard_completion:g};",
        f"# aggressive: most help with wrong trials completed >= {c.min_wrong_corrected:g} and "
        f"time lost <= {c.max_time_lost_s:g} s.",
    ]
    for mode in (TIMID, AGGRESSIVE):
        chosen = result.chosen.get(mode)
        out.append("")
        out.append(f"[modes.{mode}]")
        if chosen is None:
            out.append(f"# no {mode} setting of the grid met the criterion: widen the grid")
            continue
        out.append(f"# evidence: {_evidence(chosen)}")
        out.append(
            f"arbitration = {chosen.setting.inline_table(saturation=result.saturation)}"
            if mode == TIMID
            else f"arbitration = {chosen.setting.inline_table(saturation=0)}"
        )
    return "\n".join(out) + "\n"


def _evidence(m: Measure) -> str:
    text = f"rate {m.rate:.2f} over {m.trials} trials of {m.participants} participants"
    if m.time_lost_s is not None:
        text += f", time lost {m.time_lost_s:.1f} s"
    return text + f", help {m.help:.3f}"


def write(result: SweepResult, out: Path) -> dict[str, Path]:
    """Write ``sweep.csv``, ``sweep.json``, ``chosen.toml`` and ``sweep.png`` into ``out``."""
    paths = {
        "csv": out / "sweep.csv",
        "json": out / "sweep.json",
        "toml": out / "chosen.toml",
        "png": out / "sweep.png",
    }
    with paths["csv"].open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows(result))
    evidence = {
        "protocol": result.protocol,
        "participants": result.participants,
        "seed": result.seed,
        "criteria": result.criteria.as_dict(),
        "saturation": result.saturation,
        "rows": rows(result),
        "chosen": {mode: None if m is None else m.row() for mode, m in result.chosen.items()},
        "today": result.verdict(),
        "errors": list(result.errors),
    }
    paths["json"].write_text(json.dumps(evidence, indent=2) + "\n", encoding="utf-8")
    paths["toml"].write_text(snippet(result), encoding="utf-8")
    figure(result, paths["png"])
    return paths


def figure(result: SweepResult, path: Path) -> None:
    """Two panels, one per mode: the criterion's rate against help, threshold dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    c = result.criteria
    for ax, mode, limit, title in (
        (axes[0], TIMID, c.min_hard_completion, "timid: hard task completed"),
        (axes[1], AGGRESSIVE, c.min_wrong_corrected, "aggressive: wrong trials completed"),
    ):
        ms = [m for m in result.measures if m.setting.mode == mode]
        for m in ms:
            colour = "tab:green" if m.passes else "tab:red"
            ax.scatter(m.help, m.rate, color=colour, s=40, zorder=3)
            label = (
                f"{m.setting.value('alpha_max'):g}"
                if mode == TIMID
                else f"{m.setting.value('threshold'):g}/{m.setting.value('alpha_high'):g}"
            )
            if m.setting.D is not None:
                label += f" D={m.setting.D:g}"
            ax.annotate(
                label, (m.help, m.rate), textcoords="offset points", xytext=(4, 4), fontsize=7
            )
            if result.current[mode] == m.setting:
                ax.scatter(m.help, m.rate, s=160, facecolors="none", edgecolors="black", zorder=4)
            if result.chosen.get(mode) == m:
                ax.scatter(
                    m.help, m.rate, s=260, marker="*", color="gold", edgecolors="black", zorder=5
                )
        ax.axhline(limit, ls="--", color="grey", lw=1)
        ax.set_xlabel("help: area under alpha(c)")
        ax.set_ylabel("share of trials completed")
        ax.set_ylim(-0.05, 1.05)
        ax.set_title(title, fontsize=10)
        ax.text(
            0.01,
            0.01,
            "labels: alpha_max" if mode == TIMID else "labels: threshold/alpha_high",
            transform=ax.transAxes,
            fontsize=7,
            color="grey",
        )
    fig.suptitle(
        f"Arbitration sweep, {result.participants} simulated participants per setting "
        "(green passes; circle today's, star chosen)",
        fontsize=10,
    )
    fig.savefig(path, dpi=120)
    plt.close(fig)

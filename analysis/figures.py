"""The paper's figures from our data (matplotlib, Agg canvas, no pyplot state).

- Fig. 7: arbitration ``alpha(c)`` of each mode, built by ``app.blending.arbitration_from_config``
  from the protocol's ``[modes.*].arbitration`` tables.
- Fig. 8: time per task and mode, and the preference per task, means with standard errors.
- Fig. 9: prediction success rate per predictor and mode (means +- SE), and one trajectory
  coloured by whether each predictor was right at each point (green) or wrong (red).
- Power curves: power per test against the number of participants, Monte-Carlo 95% CI, one
  panel per hypothesis, the paper's form dashed and the reviewer's solid.
Every figure is written as PNG and SVG.
"""

from __future__ import annotations

import io
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from analysis.prediction_eval import Replay, first_lasting_correct
from app.blending import StatefulArbitration, arbitration_from_config

TASK_ORDER = ["easy-right", "easy-wrong", "hard-right", "hard-wrong"]
TASK_LABELS = {
    "easy-right": "Easy&Right",
    "easy-wrong": "Easy&Wrong",
    "hard-right": "Hard&Right",
    "hard-wrong": "Hard&Wrong",
}
MODE_COLORS = {"timid": "#4c72b0", "aggressive": "#dd8452", "yielding": "#55a868"}
OTHER_MODE_COLORS = ("#8172b2", "#937860", "#da8bc3", "#8c8c8c", "#ccb974", "#64b5cd")
"""Colours for modes not named in MODE_COLORS, handed out in order (see :func:`mode_colors`)."""
RIGHT, WRONG = "#2ca02c", "#d62728"


@dataclass(frozen=True)
class SavedFigure:
    name: str
    title: str
    png: Path
    svg: Path

    def inline_svg(self) -> str:
        """The SVG without its XML prologue, ready to embed in HTML."""
        text = self.svg.read_text(encoding="utf-8")
        text = re.sub(r"<\?xml[^>]*\?>\s*", "", text)
        return re.sub(r"<!DOCTYPE[^>]*>\s*", "", text)


def mode_colors(modes: Sequence[str]) -> dict[str, str]:
    """A distinct colour per mode: the fixed ones of MODE_COLORS, then OTHER_MODE_COLORS in
    order (cycled past six unnamed modes), so any number of modes can be told apart."""
    others = iter(OTHER_MODE_COLORS * (1 + len(modes) // len(OTHER_MODE_COLORS)))
    return {m: MODE_COLORS[m] if m in MODE_COLORS else next(others) for m in modes}


def _new(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save(fig: Figure, out_dir: Path, name: str, title: str) -> SavedFigure:
    """Write ``name.png`` (150 dpi) and ``name.svg`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    png, svg = out_dir / f"{name}.png", out_dir / f"{name}.svg"
    with rc_context({"svg.hashsalt": name, "svg.fonttype": "path"}):
        fig.savefig(png, dpi=150)
        buf = io.StringIO()
        fig.savefig(buf, format="svg", metadata={"Date": None})
    svg.write_text(buf.getvalue(), encoding="utf-8")
    return SavedFigure(name=name, title=title, png=png, svg=svg)


def arbitration_figure(
    arbitrations: Mapping[str, Mapping[str, Any]], *, rate_hz: float = 100.0
) -> Figure:
    """Fig. 7: ``alpha`` against confidence ``c`` for each mode's arbitration table.

    A stateful kind (``app.blending.adaptive``: yielding, user_confidence) has a family of
    curves, ``min(a(c), max(floor, g a(c)))`` over its gain ``g``: drawn at ``g = 1`` (the user
    agrees, or is trusted: solid) and at ``g = 0`` (fully yielded: dashed). ``rate_hz``, the
    protocol's control rate, only builds such kinds; the curves do not depend on it."""
    fig = _new(4.5, 3.2)
    ax = fig.add_subplot()
    c = np.linspace(0.0, 1.0, 801)
    colors = mode_colors(list(arbitrations))
    for name, table in arbitrations.items():
        arb = arbitration_from_config(
            dict(table), where=f"modes.{name}.arbitration", rate_hz=rate_hz
        )
        if isinstance(arb, StatefulArbitration):
            arb.reset()
        alpha = np.array([arb(float(x)) for x in c])
        # a stateful kind's full curve often equals another mode's: thinner, drawn on top
        lw = 1.2 if isinstance(arb, StatefulArbitration) else 2.0
        ax.plot(c, alpha, lw=lw, label=name, color=colors[name])
        if isinstance(arb, StatefulArbitration):
            arb.gain = 0.0
            low = np.array([arb(float(x)) for x in c])
            ax.plot(c, low, lw=1.5, ls="--", label=f"{name}, yielded", color=colors[name])
            arb.reset()
    ax.set(
        xlabel="confidence c",
        ylabel="arbitration α",
        xlim=(0, 1),
        ylim=(-0.02, 1.02),
        title="Arbitration by mode (Fig. 7)",
    )
    ax.legend(frameon=False)
    ax.grid(alpha=0.3)
    return fig


def _bars(
    ax: Any,
    table: pd.DataFrame,
    value: str,
    err: str,
    groups: list[str],
    series: list[str],
    series_col: str,
    group_col: str,
    colors: Mapping[str, str] | None = None,
) -> None:
    width = 0.8 / max(1, len(series))
    x = np.arange(len(groups))
    for i, s in enumerate(series):
        sub = table[table[series_col] == s].set_index(group_col).reindex(groups)
        ax.bar(
            x + (i - (len(series) - 1) / 2) * width,
            sub[value],
            width,
            yerr=sub[err],
            capsize=3,
            label=s,
            color=(colors or {}).get(s),
        )
    ax.set_xticks(x, [TASK_LABELS.get(g, g) for g in groups])


def timing_preference_figure(
    summary: pd.DataFrame,
    preference: pd.DataFrame | None = None,
    *,
    modes: Sequence[str] = ("timid", "aggressive"),
    reference: str | None = None,
    time_label: str = "time to complete (s)",
) -> Figure:
    """Fig. 8: (a) mean time per task and mode +- SE (``summary``: task, mode, mean, se);
    (b) the preference per task, re-centred on ``reference`` +- SE (``preference``: task,
    mean, se; left out when ``None`` or empty). No error bar where the SE is not defined
    (one participant)."""
    with_pref = preference is not None and not preference.empty
    fig = _new(9.0 if with_pref else 5.5, 3.4)
    axes = fig.subplots(1, 2 if with_pref else 1, squeeze=False)[0]
    tasks = _tasks(summary)
    present = _modes_present(summary, modes)
    _bars(axes[0], summary, "mean", "se", tasks, present, "mode", "task", mode_colors(present))
    axes[0].set(ylabel=time_label, title="(a) Time per task and mode")
    top = axes[0].get_ylim()[1]
    axes[0].set_ylim(0, top * 1.18)  # head-room: the legend sits above the bars, not on them
    axes[0].legend(frameon=False, loc="upper left", ncols=len(present))
    if with_pref:
        ax2 = axes[1]
        pref = preference.set_index("task").reindex(tasks)  # type: ignore[union-attr]
        ax2.bar(
            np.arange(len(tasks)), pref["mean"], 0.6, yerr=pref["se"], capsize=3, color="#8172b2"
        )
        ax2.axhline(0, color="k", lw=0.8)
        ax2.set_xticks(np.arange(len(tasks)), [TASK_LABELS.get(t, t) for t in tasks])
        other = next((m for m in present if m != reference), "other")
        ax2.set(
            ylim=(-3.2, 3.2),
            ylabel=f"← {other}   preference   {reference or 'second'} →",
            title="(b) Preference per task",
        )
    return fig


def _modes_present(summary: pd.DataFrame, modes: Sequence[str]) -> list[str]:
    """The modes in ``summary``: ``modes``' order first, then any others as found."""
    found = list(dict.fromkeys(summary["mode"]))
    return [m for m in modes if m in found] + [m for m in found if m not in modes]


def _tasks(summary: pd.DataFrame) -> list[str]:
    found = set(summary["task"])
    return [t for t in TASK_ORDER if t in found] or sorted(found)


def ratings_figure(
    summary: pd.DataFrame, *, modes: Sequence[str] = ("timid", "aggressive"), points: int = 7
) -> Figure:
    """Fig. 8 (ratings): one panel per rated item, mean rating per task and mode +- SE
    (``summary``: item, task, mode, mean, se; ``analysis.ratings.rating_summary``)."""
    items = list(dict.fromkeys(summary["item"]))
    fig = _new(3.6 * len(items) + 0.6, 3.4)
    axes = fig.subplots(1, len(items), squeeze=False)[0]
    tasks = _tasks(summary)
    present = _modes_present(summary, modes)
    colors = mode_colors(present)
    for ax, item in zip(axes, items, strict=True):
        sub = summary[summary["item"] == item]
        _bars(ax, sub, "mean", "se", tasks, present, "mode", "task", colors)
        ax.set(ylim=(0, points + 1.4), yticks=range(1, points + 1), title=item)
        ax.tick_params(axis="x", labelsize=7)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel(f"rating (1..{points})")
    axes[0].legend(frameon=False, loc="upper left", ncols=len(present), fontsize=8)
    return fig


def prediction_figure(
    evals: pd.DataFrame,
    example: Mapping[str, Replay],
    goals: np.ndarray,
    goal_names: list[str],
    target: int,
    title: str = "",
    *,
    modes: Sequence[str] = ("timid", "aggressive"),
) -> Figure:
    """Fig. 9: (a) success rate by mode and predictor +- SE; (b, c) one trajectory (top view)
    coloured by correctness of each predictor, an arrow at the first lasting correct point."""
    fig = _new(11.0, 3.6)
    axes = fig.subplots(1, 1 + len(example))
    g = evals.groupby(["predictor", "mode"])["success_rate"]
    summ = pd.DataFrame({"mean": g.mean(), "se": g.std() / np.sqrt(g.count())}).reset_index()
    preds = list(dict.fromkeys(evals["predictor"]))
    modes = [m for m in modes if m in set(summ["mode"])]
    width = 0.8 / max(1, len(preds))
    x = np.arange(len(modes))
    for i, p in enumerate(preds):
        sub = summ[summ.predictor == p].set_index("mode").reindex(modes)
        axes[0].bar(
            x + (i - (len(preds) - 1) / 2) * width,
            sub["mean"],
            width,
            yerr=sub["se"],
            capsize=3,
            label=p,
        )
    axes[0].set_xticks(x, modes)
    axes[0].set(ylim=(0, 1.2), ylabel="success rate", title="(a) Prediction success")
    axes[0].legend(frameon=False, loc="upper left", ncols=2)
    for ax, (name, rep), letter in zip(axes[1:], example.items(), "bcdefg", strict=False):
        assert rep.correct is not None
        pts = rep.points
        ax.plot(pts[:, 0], pts[:, 1], color="0.8", lw=0.8, zorder=1)
        step = max(1, len(pts) // 150)
        idx = np.arange(0, len(pts), step)
        ax.scatter(
            pts[idx, 0], pts[idx, 1], s=9, zorder=2, c=np.where(rep.correct[idx], RIGHT, WRONG)
        )
        for k, (gx, gy) in enumerate(goals[:, :2]):
            ax.scatter(
                [gx],
                [gy],
                marker="*" if k == target else "s",
                s=120,
                color="k" if k == target else "0.5",
                zorder=3,
            )
            ax.annotate(goal_names[k], (gx, gy), textcoords="offset points", xytext=(5, 5))
        first = first_lasting_correct(rep.correct)
        if first is not None:
            fx, fy = pts[first, :2]
            ax.annotate(
                "",
                xy=(fx, fy),
                xytext=(fx - 0.06, fy + 0.06),
                arrowprops={"arrowstyle": "->", "lw": 1.5},
            )
        share = float(rep.correct.mean())
        ax.set(
            xlabel="x (m)",
            ylabel="y (m)",
            aspect="equal",
            title=f"({letter}) {name}: correct {share:.0%} of the time",
        )
    if title:
        fig.suptitle(title, fontsize=9)
    return fig


FORM_STYLES = {
    "as in the paper": ("--", "paper's form"),
    "reviewer": ("-", "reviewer's form"),
    "both (participant-level already)": (":", "both forms"),
}


def _error_bars(value: pd.Series, low: pd.Series, high: pd.Series) -> np.ndarray:
    """matplotlib's ``yerr`` (below, above) for an interval around ``value``: never negative,
    even where the interval's end equals the value up to rounding (power 0 or 1)."""
    below = np.asarray(value, float) - np.asarray(low, float)
    above = np.asarray(high, float) - np.asarray(value, float)
    return np.clip(np.nan_to_num(np.vstack([below, above])), 0.0, None)


def power_figure(table: pd.DataFrame, *, target: float = 0.8) -> Figure:
    """Power against N per test (``analysis.power.COLUMNS``), error bars = Wilson 95% CI."""
    hyps = list(dict.fromkeys(table["hypothesis"]))
    fig = _new(5.2 * len(hyps), 5.6)
    axes = fig.subplots(1, len(hyps), squeeze=False)[0]
    colours = [f"C{i}" for i in range(10)]
    for ax, h in zip(axes, hyps, strict=True):
        sub = table[table["hypothesis"] == h]
        names = list(dict.fromkeys(sub["test"]))
        for i, name in enumerate(names):
            for form, g in sub[sub["test"] == name].groupby("form", sort=False):
                g = g.sort_values("n")
                ax.errorbar(
                    g["n"],
                    g["power"],
                    yerr=_error_bars(g["power"], g["ci_low"], g["ci_high"]),
                    color=colours[i % 10],
                    linestyle=FORM_STYLES.get(str(form), ("-", ""))[0],
                    marker="o",
                    markersize=3,
                    capsize=2,
                    linewidth=1.2,
                    label=f"{name} ({FORM_STYLES.get(str(form), ('', form))[1]})",
                )
        ax.axhline(target, color="0.5", linewidth=0.8, linestyle=":")
        ax.set_ylim(-0.02, 1.02)
        ax.set_xticks(sorted(sub["n"].unique()))
        ax.set_xlabel("participants N")
        ax.set_ylabel("power")
        ax.set_title(h)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
        ax.grid(alpha=0.3)
    return fig

"""Task success beside time: how often each condition ended with the target lifted.

Time alone hides a mode that is fast when it works but fails more often (an arm that carries
the gripper to the wrong object can knock it over). For every task and mode over completed
task trials, ``success_summary`` gives the share of trials whose outcome is ``success`` with its
Wilson 95% interval, for ``n`` trials and ``k`` successes (z = 1.96):

    centre = (k + z^2/2) / (n + z^2),  half-width = z / (n + z^2) * sqrt(k (n - k) / n + z^2 / 4).

``success_comparisons`` compares every pair of modes within a task on the same participants:
McNemar's exact test, a two-sided binomial test with p = 1/2 on the discordant pairs (one mode
succeeded, the other did not), Bonferroni-adjusted over the mode pairs of the task. Any number
of modes works; the paper's design has two.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import combinations

import pandas as pd
from scipy.stats import binomtest

from analysis.load import StudyTables
from analysis.render import Section, Table, fmt, fmt_p

Z95 = 1.959963984540054


def wilson_interval(successes: int, n: int, *, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a binomial share (``(nan, nan)`` for ``n = 0``)."""
    if n <= 0:
        return math.nan, math.nan
    denom = n + z * z
    centre = (successes + z * z / 2) / denom
    half = z / denom * math.sqrt(successes * (n - successes) / n + z * z / 4)
    return max(0.0, centre - half), min(1.0, centre + half)


def _done(trials: pd.DataFrame) -> pd.DataFrame:
    need = {"task", "mode", "phase", "status", "outcome", "participant"}
    if not need <= set(trials.columns):
        return pd.DataFrame()
    return trials[(trials["phase"] == "task") & (trials["status"] == "completed")]


def _modes_in_order(done: pd.DataFrame, modes: Sequence[str] | None) -> list[str]:
    """The modes present, in ``modes``' order (the protocol's), then any others as found."""
    present = list(dict.fromkeys(done["mode"]))
    first = [m for m in (modes or ()) if m in present]
    return first + [m for m in present if m not in first]


def success_summary(trials: pd.DataFrame, *, modes: Sequence[str] | None = None) -> pd.DataFrame:
    """Per task and mode: ``trials``, ``successes``, ``success_rate``, ``ci_low``, ``ci_high``
    (tasks sorted, modes in ``modes``' order)."""
    done = _done(trials)
    if done.empty:
        return pd.DataFrame()
    rank = {m: i for i, m in enumerate(_modes_in_order(done, modes))}
    rows = []
    for (task, mode), g in done.groupby(["task", "mode"], sort=False):
        n, k = len(g), int((g["outcome"] == "success").sum())
        lo, hi = wilson_interval(k, n)
        rows.append(
            {
                "task": task,
                "mode": mode,
                "trials": n,
                "successes": k,
                "success_rate": k / n,
                "ci_low": lo,
                "ci_high": hi,
            }
        )
    out = pd.DataFrame(rows)
    out = out.sort_values(["task", "mode"], key=lambda s: s.map(rank) if s.name == "mode" else s)
    return out.reset_index(drop=True)


def success_comparisons(
    trials: pd.DataFrame, *, modes: Sequence[str] | None = None
) -> pd.DataFrame:
    """Every mode pair within every task: paired success difference and McNemar's exact test.

    Columns: ``task``, ``comparison`` (``first - second``), ``pairs`` (participants with both
    runs), ``difference`` (share of successes, first minus second), ``first_only``,
    ``second_only`` (discordant pairs), ``p``, ``p_bonferroni`` (over the task's mode pairs)."""
    done = _done(trials)
    if done.empty:
        return pd.DataFrame()
    order = _modes_in_order(done, modes)
    ok = done.assign(ok=(done["outcome"] == "success").astype(int))
    wide = ok.pivot_table(index=["participant", "task"], columns="mode", values="ok", aggfunc="max")
    pairs = list(combinations(order, 2))
    rows = []
    for task, w in wide.groupby(level="task", sort=True):
        for a, b in pairs:
            both = w[[a, b]].dropna()
            if both.empty:
                continue
            first_only = int(((both[a] == 1) & (both[b] == 0)).sum())
            second_only = int(((both[a] == 0) & (both[b] == 1)).sum())
            discordant = first_only + second_only
            p = binomtest(first_only, discordant, 0.5).pvalue if discordant else 1.0
            rows.append(
                {
                    "task": task,
                    "comparison": f"{a} - {b}",
                    "pairs": len(both),
                    "difference": float((both[a] - both[b]).mean()),
                    "first_only": first_only,
                    "second_only": second_only,
                    "p": float(p),
                    "p_bonferroni": min(1.0, float(p) * len(pairs)),
                }
            )
    return pd.DataFrame(rows)


def success_section(
    tables: StudyTables, *, modes: Sequence[str] | None = None, tests: bool = True
) -> Section | None:
    """The report's section on task success (``None`` without completed task trials);
    without ``tests`` (too few participants) the shares only, without intervals or tests."""
    summary = success_summary(tables.trials, modes=modes)
    if summary.empty:
        return None
    sec = Section("Task success by condition")
    if not tests:
        sec.paragraphs.append(
            "Share of completed task trials that ended with the target lifted (outcome "
            "success). Too few participants for intervals or tests (see the data section)."
        )
        shown = pd.DataFrame(
            {
                "task": summary["task"],
                "mode": summary["mode"],
                "trials": summary["trials"],
                "success": [f"{r.successes}/{r.trials}" for r in summary.itertuples()],
            }
        )
        sec.tables.append(Table("Success by task and mode", shown))
        return sec
    sec.paragraphs.append(
        "Share of completed task trials that ended with the target lifted (outcome success), "
        "with its Wilson 95% interval; then every pair of modes within a task on the same "
        "participants: McNemar's exact test on the discordant pairs, Bonferroni over the task's "
        "mode pairs."
    )
    shown = pd.DataFrame(
        {
            "task": summary["task"],
            "mode": summary["mode"],
            "trials": summary["trials"],
            "success rate [95% CI]": [
                f"{fmt(r.success_rate)} [{fmt(r.ci_low)}, {fmt(r.ci_high)}]"
                for r in summary.itertuples()
            ],
        }
    )
    sec.tables.append(Table("Success rate by task and mode", shown))
    comp = success_comparisons(tables.trials, modes=modes)
    if not comp.empty:
        sec.tables.append(
            Table(
                "Success: paired mode comparisons per task (McNemar exact)",
                pd.DataFrame(
                    {
                        "task": comp["task"],
                        "comparison": comp["comparison"],
                        "pairs": comp["pairs"],
                        "difference": comp["difference"].map(fmt),
                        "first only / second only": [
                            f"{r.first_only} / {r.second_only}" for r in comp.itertuples()
                        ],
                        "p": comp["p"].map(fmt_p),
                        "p (Bonferroni)": comp["p_bonferroni"].map(fmt_p),
                    }
                ),
                note="Difference = share of successes, first mode minus second.",
            )
        )
    return sec

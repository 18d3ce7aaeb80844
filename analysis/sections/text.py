"""Text shared by the report's sections: intervals, df, test statistics, ANOVA tables, and why
the paper's values are not shown."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from analysis.render import fmt, fmt_p
from analysis.statistics_rows import ASSUMES
from analysis.study_results import StudyResults
from analysis.timing import FACTORS, LEVELS


def anova_table(
    table: pd.DataFrame, analysis: str, stats: pd.DataFrame, with_paper: bool = True
) -> pd.DataFrame:
    """An ANOVA table; with the paper's F and p beside ours when ``with_paper``."""
    pub = stats[stats.analysis == analysis].set_index("effect")
    rows = []
    for r in table.itertuples():
        paper = pub.loc[r.effect] if r.effect in pub.index else None
        row = {
            "effect": r.effect,
            "df": f"{fmt(r.df1, 0)}, {fmt(r.df2, 0)}",
            "F": fmt(r.F),
            "p": fmt_p(r.p),
            "partial η²": fmt(r.np2, 3),
        }
        if with_paper:
            row["paper F"] = fmt(paper["paper_value"]) if paper is not None else ""
            row["paper p"] = fmt(paper["paper_p"]) if paper is not None else ""
        rows.append(row)
    return pd.DataFrame(rows)


def assumes(analysis: str) -> str:
    return f"Assumes: {ASSUMES[analysis]}."


def ci(lo: float, hi: float, digits: int = 2) -> str:
    """``[lo, hi]``, or "–" when either end is not defined (never an empty ``[, ]``)."""
    if pd.isna(lo) or pd.isna(hi):
        return "–"
    return f"[{fmt(lo, digits)}, {fmt(hi, digits)}]"


def with_ci(value: float, lo: float, hi: float, digits: int = 2) -> str:
    if pd.isna(value):
        return ""
    interval = f" {ci(lo, hi, digits)}" if pd.notna(lo) and pd.notna(hi) else ""
    return f"{fmt(value, digits)}{interval}"


def df_text(v: float) -> str:
    """Integer df as integers (within rounding: a boundary fit's n - p), Satterthwaite df to
    one decimal."""
    return fmt(float(round(v)), 0) if abs(v - round(v)) < 1e-9 * max(1.0, abs(v)) else fmt(v, 1)


def stat_text(stat: str, df1: float, df2: float, value: float, p: float) -> str:
    df = df_text(df1) if pd.isna(df2) else f"{df_text(df1)}, {df_text(df2)}"
    return f"{stat}({df}) = {fmt(value)}, p {'' if fmt_p(p).startswith('<') else '= '}{fmt_p(p)}"


def rm_table(table: pd.DataFrame, analysis: str, stats: pd.DataFrame) -> pd.DataFrame:
    """F-test rows with partial eta squared [95% CI]; for an RM ANOVA with an effect of more
    than 1 df also GG/HF epsilon and p and Mauchly's test."""
    st = stats[stats.analysis == analysis].set_index("effect")
    out = pd.DataFrame(
        {
            "effect": table["effect"],
            "df": [
                f"{fmt(a, 0)}, {fmt(b, 0)}" for a, b in zip(table["df1"], table["df2"], strict=True)
            ],
            "F": table["F"].map(fmt),
            "p": table["p"].map(fmt_p),
            "partial η² [95% CI]": [
                with_ci(r.np2, st.loc[r.effect, "ci_low"], st.loc[r.effect, "ci_high"], 3)
                for r in table.itertuples()
            ],
        }
    )
    if "eps_gg" in table.columns and (table["df1"] > 1).any():
        multi = table["df1"] > 1
        out["ε GG"] = np.where(multi, table["eps_gg"].map(lambda v: fmt(v, 3)), "")
        out["p GG"] = np.where(multi, table["p_gg"].map(fmt_p), "")
        out["ε HF"] = np.where(multi, table["eps_hf"].map(lambda v: fmt(v, 3)), "")
        out["p HF"] = np.where(multi, table["p_hf"].map(fmt_p), "")
        out["Mauchly W"] = table["mauchly_W"].map(lambda v: fmt(v, 3))
        out["Mauchly p"] = table["mauchly_p"].map(fmt_p)
    return out


def design_text(levels: Mapping[str, tuple[str, ...]]) -> str:
    return "; ".join(f"{f}: {', '.join(v)}" for f, v in levels.items())


PAPER_DESIGN = "the paper's 2 x 2 x 2 (" + design_text({f: LEVELS[f] for f in FACTORS}) + ")"


def no_paper_values(res: StudyResults, what: str = "design") -> str:
    if what == "predictors":
        return (
            "The predictors replayed differ from the paper's (amnesic, and memory-based "
            "with the squared-velocity cost of eq. 9), so the paper's values are not shown."
        )
    levels = res.timing.levels if res.timing is not None else None
    ours = f" ({design_text(levels)})" if levels else ""
    return f"This design{ours} differs from {PAPER_DESIGN}, so the paper's values are not shown."

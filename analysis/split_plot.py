"""Split-plot (mixed-design) ANOVA: within-subject factors crossed with between-subject factors.

Each subject ``s`` has cell means ``y_s`` over the within cells and one level of every between
factor. For a within effect ``E`` (orthonormal contrasts ``K_E``, :func:`effect_contrasts`; for
the between stratum ``K = 1 / sqrt(cells)``) the scores ``Z = Y K_E`` are regressed on the
between design ``X`` (sum-to-zero coding, full factorial, one column per between cell). Then
``SS_{T x E} = tr(Z' (H_full - H_{-T}) Z)`` -- the type III sum of squares of between term ``T``
(the intercept for ``E`` itself), summed over ``E``'s contrasts -- and the error of the stratum
``SS_{E x S/B} = tr(R'R)`` with ``R`` the residuals of the full between model, on
``df_E (n - g)`` df for ``g`` between cells; ``F = (SS / (df_T df_E)) / (SS_err / df_err)``.
This is the textbook split-plot decomposition (between effects against subjects within groups,
within effects and their interactions with the between factors against ``E x subjects within
groups``); with no between factor it is :func:`analysis.rm_anova.rm_anova_cells` exactly, and
with unequal groups it is SPSS GLM's type III repeated-measures test. GG/HF epsilon and
Mauchly's test use the residuals pooled within groups (``n - g`` df).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import special

from analysis.anova import factor_blocks
from analysis.design import CellData, cell_means, effect_name, effect_terms, require_columns
from analysis.errors import DesignError
from analysis.rm_anova import COLUMNS as RM_COLUMNS
from analysis.rm_anova import effect_contrasts, sphericity

COLUMNS = [*RM_COLUMNS, "error"]
""":data:`analysis.rm_anova.COLUMNS` and the error term each effect is tested against."""


@dataclass(frozen=True)
class SplitPlotResult:
    """``table``: one row per effect (``COLUMNS``), between effects and within effects each with
    their interactions with the between factors; ``groups``: each subject's between levels."""

    table: pd.DataFrame
    n_subjects: int
    cells: CellData
    groups: pd.DataFrame
    between: tuple[str, ...]
    notes: tuple[str, ...]


def subject_levels(
    data: pd.DataFrame, *, subject: str, between: Sequence[str], subjects: Sequence[str]
) -> pd.DataFrame:
    """One row per subject (in ``subjects``' order) with its level of every between factor;
    DesignError when a subject has two levels of one (then the factor is not between)."""
    rows = data[[subject, *between]].astype({subject: str})
    for f in between:
        rows[f] = data[f].astype("string")
        n_levels = rows.dropna(subset=[f]).groupby(subject)[f].nunique()
        mixed = list(n_levels.index[n_levels > 1])
        if mixed:
            raise DesignError(
                f"factor {f!r} is declared between subjects, but subject(s) "
                f"{', '.join(map(str, mixed[:5]))} have more than one of its levels; declare it "
                "within subjects, or fix the data"
            )
    first = rows.dropna(subset=list(between)).groupby(subject, sort=False).first()
    lacking = [s for s in subjects if s not in first.index]
    if lacking:
        raise DesignError(
            f"subject(s) {', '.join(lacking[:5])} have no level of the between factor(s) "
            f"{', '.join(between)}; fill them in or leave those subjects out"
        )
    out = first.reindex(list(subjects)).reset_index()
    for f in between:
        s = data[f]
        cats = (
            [str(c) for c in s.cat.categories]
            if isinstance(s.dtype, pd.CategoricalDtype)
            else sorted(set(out[f].astype(str)))
        )
        out[f] = pd.Categorical(out[f].astype(str), categories=cats)
    return out


def _sse(x: np.ndarray, z: np.ndarray) -> float:
    """Residual sum of squares of every column of ``z`` regressed on ``x``, summed."""
    beta, *_ = np.linalg.lstsq(x, z, rcond=None)
    r = z - x @ beta
    return float((r * r).sum())


def _between_design(
    groups: pd.DataFrame, between: Sequence[str]
) -> dict[tuple[int, ...], np.ndarray]:
    """The intercept (key ``()``) and each between term's sum-to-zero columns."""
    n = len(groups)
    blocks: dict[tuple[int, ...], np.ndarray] = {(): np.ones((n, 1))}
    if between:
        _, coded = factor_blocks(groups, list(between))
        blocks.update(coded)
    return blocks


def _stratum_rows(
    z: np.ndarray,
    blocks: dict[tuple[int, ...], np.ndarray],
    *,
    within_name: str,
    between: Sequence[str],
    dfe: int,
) -> list[dict[str, float | str]]:
    """The F tests of one within stratum (scores ``z``): each between term's SS against the
    stratum's error on ``q dfe`` df, ``dfe = n - g`` (module docstring)."""
    x_full = np.column_stack(list(blocks.values()))
    resid_beta, *_ = np.linalg.lstsq(x_full, z, rcond=None)
    resid = z - x_full @ resid_beta
    ss_err = float((resid * resid).sum())
    q = z.shape[1]
    sph = sphericity(resid, df=dfe)
    error = f"{within_name + ' x ' if within_name else ''}subjects" + (
        f" within {' x '.join(between)}" if between else ""
    )
    rows = []
    for term, block in blocks.items():
        if not term and not within_name:
            continue  # the grand mean
        kept = [b for t, b in blocks.items() if t != term]
        sse_reduced = _sse(np.column_stack(kept), z) if kept else float((z * z).sum())
        ss = max(sse_reduced - ss_err, 0.0)
        df1 = block.shape[1] * q
        names = [effect_name(between, term)] if term else []
        rows.append(
            _row(
                ":".join([*names, *([within_name] if within_name else [])]),
                ss=ss,
                ss_err=ss_err,
                df1=df1,
                df2=q * dfe,
                sph=sph,
                error=error,
            )
        )
    return rows


def _row(
    effect: str,
    *,
    ss: float,
    ss_err: float,
    df1: int,
    df2: int,
    sph: dict[str, float],
    error: str,
) -> dict[str, float | str]:
    f = (ss / df1) / (ss_err / df2) if ss_err > 0 else np.inf

    def p_at(eps: float) -> float:
        return float(special.fdtrc(df1 * eps, df2 * eps, f)) if np.isfinite(f) else 0.0

    total = ss + ss_err
    return {
        "effect": effect,
        "df1": float(df1),
        "df2": float(df2),
        "F": float(f),
        "p": p_at(1.0),
        "np2": ss / total if total > 0 else np.nan,
        "SS": ss,
        "SS_error": ss_err,
        "eps_gg": sph["eps_gg"],
        "p_gg": p_at(sph["eps_gg"]),
        "eps_hf": sph["eps_hf"],
        "p_hf": p_at(sph["eps_hf"]),
        "mauchly_W": sph["mauchly_W"],
        "mauchly_chi2": sph["mauchly_chi2"],
        "mauchly_df": sph["mauchly_df"],
        "mauchly_p": sph["mauchly_p"],
        "error": error,
    }


def split_plot_cells(cells: CellData, groups: pd.DataFrame, between: Sequence[str]) -> pd.DataFrame:
    """The ANOVA table of complete cell means ``cells`` and the subjects' between levels."""
    between = list(between)
    blocks = _between_design(groups, between)
    n = len(cells.subjects)
    g = int(groups[between].drop_duplicates().shape[0]) if between else 1
    full = int(np.prod([len(groups[f].cat.categories) for f in between])) if between else 1
    if g < full:
        raise DesignError(
            f"{full - g} of the {full} between-subject groups ({' x '.join(between)}) have no "
            "subject; every combination of the between factors' levels needs participants"
        )
    if n - g < 1:
        raise DesignError(
            f"{n} subject(s) in {g} between-subject group(s) leave no error df; the split-plot "
            "ANOVA needs more subjects than groups"
        )
    n_levels = [len(lv) for lv in cells.levels]
    rows = []
    for term in [(), *effect_terms(cells.factors)]:
        z = cells.values @ effect_contrasts(n_levels, term)
        rows += _stratum_rows(
            z,
            blocks,
            within_name=effect_name(cells.factors, term) if term else "",
            between=between,
            dfe=n - g,
        )
    order = {name: i for i, name in enumerate(_effect_order(between, cells.factors))}
    rows.sort(key=lambda r: order.get(str(r["effect"]), len(order)))
    return pd.DataFrame(rows, columns=COLUMNS)


def _effect_order(between: Sequence[str], within: Sequence[str]) -> list[str]:
    """Effects named as the rows are, main effects first, then two-way, ... (between first)."""
    factors = [*between, *within]
    nb = len(between)
    out = []
    for term in effect_terms(factors):
        b = [factors[i] for i in term if i < nb]
        w = [factors[i] for i in term if i >= nb]
        out.append(":".join([*b, *w]))
    return out


def split_plot_anova(
    data: pd.DataFrame,
    *,
    dv: str,
    subject: str,
    within: Sequence[str],
    between: Sequence[str] = (),
    drop_incomplete: bool = False,
) -> SplitPlotResult:
    """Split-plot ANOVA of ``dv`` on the ``within`` and ``between`` factors of long ``data``
    (repeated rows per subject and cell averaged; incomplete subjects raise DesignError, or
    are dropped with ``drop_incomplete=True``). See the module docstring."""
    between = list(between)
    clash = sorted(set(between) & set(within))
    if clash:
        raise DesignError(
            f"factor(s) {', '.join(clash)} given as both within and between subjects; "
            "each factor is one or the other"
        )
    require_columns(data, [*between])
    cells = cell_means(data, dv=dv, subject=subject, within=within, drop_incomplete=drop_incomplete)
    groups = subject_levels(data, subject=subject, between=between, subjects=cells.subjects)
    notes = list(cells.notes)
    for f in between:
        counts = groups[f].value_counts(sort=False)
        if (counts == 0).any() or len(counts) < 2:
            raise DesignError(
                f"between factor {f!r} needs subjects at two or more levels; found "
                + ", ".join(f"{k}: {v}" for k, v in counts.items())
            )
    if between:
        sizes = groups.groupby(between, observed=True).size()
        if sizes.nunique() > 1:
            notes.append(
                "unequal group sizes ("
                + ", ".join(
                    f"{' x '.join(map(str, np.atleast_1d(k)))}: {v}" for k, v in sizes.items()
                )
                + "): type III sums of squares (unweighted group means)"
            )
    return SplitPlotResult(
        table=split_plot_cells(cells, groups, between),
        n_subjects=len(cells.subjects),
        cells=cells,
        groups=groups,
        between=tuple(between),
        notes=tuple(notes),
    )

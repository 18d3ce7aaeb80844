"""Factorial ANOVA with covariates by ordinary least squares (the paper's F(1, 53) analysis).

Model: ``y = b0 + sum_terms X_T b_T + W g + e`` with sum-to-zero (effect) coding of every factor,
all interactions, and numeric covariates ``W`` entered linearly. Residual df = ``N - cells - k``
for ``k`` covariates (64 - 8 - 3 = 53 in the paper). Each effect is tested with
``F = (SS_T / df_T) / (SSE / df_resid)``.

Sums of squares are type III by default: ``SS_T = SSE(model without T) - SSE(full model)``.
With sum-to-zero contrasts this tests every effect at the unweighted cell means, adjusted for
all other effects and the covariates - the default of SPSS' GLM, which reports exactly the
paper's quantities (F(1, 53), R^2), and it does not depend on the order terms are listed in.
In a balanced factorial without covariates types II and III coincide; the covariates (and any
unbalance) make them differ, and type III keeps each factor test independent of whether its
interactions are in the model. Type II (``ss_type=2``: each term adjusted for all terms not
containing it) is available for comparison.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy import special

from analysis.design import cell_means, effect_name, effect_terms, numeric_column, require_columns
from analysis.errors import DesignError

COLUMNS = ["effect", "df1", "df2", "F", "p", "np2", "SS"]


@dataclass(frozen=True)
class FactorialAnovaResult:
    """``table``: one row per effect and covariate; fit statistics of the full model beside it."""

    table: pd.DataFrame
    r2: float
    r2_adj: float
    df_resid: int
    sse: float
    n: int
    ss_type: int
    levels: dict[str, tuple[str, ...]]
    notes: tuple[str, ...] = ()


def effect_coding(values: pd.Series, levels: Sequence[str]) -> np.ndarray:
    """``(N, k-1)`` sum-to-zero coding: level j -> e_j for j < k-1, the last level -> all -1."""
    k = len(levels)
    idx = pd.Categorical(values.astype(str), categories=list(levels)).codes
    out = np.zeros((len(values), k - 1))
    for j in range(k - 1):
        out[idx == j, j] = 1.0
    out[idx == k - 1, :] = -1.0
    return out


def factor_blocks(
    data: pd.DataFrame, factors: Sequence[str]
) -> tuple[dict[str, tuple[str, ...]], dict[tuple[int, ...], np.ndarray]]:
    """Each factor's levels (a categorical's order, else sorted) and the effect-coded columns
    of every term of the full factorial model (main effects and all their interactions,
    keyed by factor indices as in :func:`analysis.design.effect_terms`)."""
    levels: dict[str, tuple[str, ...]] = {}
    blocks: dict[tuple[int, ...], np.ndarray] = {}
    for i, f in enumerate(factors):
        s = data[f]
        if isinstance(s.dtype, pd.CategoricalDtype):
            present = set(s.astype(str))
            lv = tuple(str(c) for c in s.cat.categories if str(c) in present)
        else:
            lv = tuple(sorted(set(s.astype(str))))
        if len(lv) < 2:
            raise DesignError(
                f"factor {f!r} has {len(lv)} level{'s' if len(lv) != 1 else ''}; "
                "a factor needs at least two levels - drop it from the model"
            )
        levels[f] = lv
        blocks[(i,)] = effect_coding(s, lv)
    for t in effect_terms(factors):
        if len(t) > 1:
            cols = [
                np.prod(combo, axis=0)
                for combo in itertools.product(*[list(blocks[(i,)].T) for i in t])
            ]
            blocks[t] = np.column_stack(cols)
    return levels, blocks


def _sse(x: np.ndarray, y: np.ndarray) -> float:
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ beta
    return float(r @ r)


Part = tuple[str, tuple[int, ...] | None, np.ndarray]
"""A model term: its name, its factor indices (``None`` for a covariate), its columns."""


def factorial_anova(
    data: pd.DataFrame,
    *,
    dv: str,
    factors: Sequence[str],
    covariates: Sequence[str] = (),
    ss_type: int = 3,
) -> FactorialAnovaResult:
    """Fit the full factorial model with covariates and test every effect (see module doc)."""
    factors, covariates = list(factors), list(covariates)
    _check_roles(dv, factors, covariates, ss_type)
    require_columns(data, [dv, *factors, *covariates])
    d, y, cov_values, notes = _complete_rows(data, dv, factors, covariates)
    n = len(y)
    levels, blocks = factor_blocks(d, factors)
    _require_every_cell(d, factors, levels)
    parts: list[Part] = [(effect_name(factors, t), t, blocks[t]) for t in effect_terms(factors)]
    parts += [(c, None, col) for c, col in _covariate_columns(cov_values).items()]
    x_full = np.column_stack([np.ones(n)] + [p[2] for p in parts])
    p_cols = x_full.shape[1]
    df_resid = n - p_cols
    if df_resid <= 0:
        raise DesignError(
            f"{n} observations cannot fit {p_cols} parameters (cells + covariates); "
            "collect more data or use fewer covariates"
        )
    _require_full_rank(x_full, parts, covariates)
    sse = _sse(x_full, y)
    sst = float(((y - y.mean()) ** 2).sum())
    rows = _effect_rows(parts, y, sse=sse, df_resid=df_resid, ss_type=ss_type)
    r2 = 1.0 - sse / sst if sst > 0 else np.nan
    r2_adj = 1.0 - (1.0 - r2) * (n - 1) / df_resid
    return FactorialAnovaResult(
        table=pd.DataFrame(rows, columns=COLUMNS),
        r2=float(r2),
        r2_adj=float(r2_adj),
        df_resid=df_resid,
        sse=sse,
        n=n,
        ss_type=ss_type,
        levels=levels,
        notes=tuple(notes),
    )


def _check_roles(dv: str, factors: list[str], covariates: list[str], ss_type: int) -> None:
    if ss_type not in (2, 3):
        raise DesignError(f"ss_type must be 2 or 3, got {ss_type!r}")
    if not factors:
        raise DesignError("no factor given; name at least one factor column")
    names = [dv, *factors, *covariates]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DesignError(
            f"column(s) {', '.join(map(repr, dupes))} given in two roles; "
            "each role needs its own column"
        )


def _complete_rows(
    data: pd.DataFrame, dv: str, factors: list[str], covariates: list[str]
) -> tuple[pd.DataFrame, np.ndarray, dict[str, np.ndarray], list[str]]:
    """The rows with the dependent variable, every covariate and every factor present: the
    data, ``y``, each covariate's values, and a note on the rows left out."""
    y = numeric_column(data, dv).to_numpy()
    notes: list[str] = []
    keep = ~np.isnan(y)
    cov_values = {}
    for c in covariates:
        v = numeric_column(data, c).to_numpy()
        cov_values[c] = v
        keep &= ~np.isnan(v)
    for f in factors:
        keep &= data[f].notna().to_numpy()
    if not keep.all():
        notes.append(f"{int((~keep).sum())} row(s) with missing values were left out")
    return data.loc[keep], y[keep], {c: v[keep] for c, v in cov_values.items()}, notes


def _require_every_cell(
    d: pd.DataFrame, factors: list[str], levels: dict[str, tuple[str, ...]]
) -> None:
    observed = set(d[factors].astype(str).drop_duplicates().itertuples(index=False, name=None))
    empty = [c for c in itertools.product(*levels.values()) if c not in observed]
    if empty:
        listed = "; ".join(
            " & ".join(f"{f}={v}" for f, v in zip(factors, c, strict=True)) for c in empty[:10]
        )
        raise DesignError(
            f"{len(empty)} cell(s) of the factorial design have no data: {listed}. "
            "Every combination of factor levels needs observations."
        )


def _covariate_columns(cov_values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each covariate centred, as one column; a constant covariate raises DesignError."""
    for c, v in cov_values.items():
        if np.ptp(v) == 0:
            raise DesignError(
                f"covariate {c!r} is constant ({v[0]:g}); it cannot be estimated - "
                "drop it from the covariates"
            )
    return {c: (v - v.mean())[:, None] for c, v in cov_values.items()}


def _require_full_rank(x_full: np.ndarray, parts: list[Part], covariates: list[str]) -> None:
    """DesignError naming the covariates that are linear in the rest, if the design is
    rank-deficient."""
    n, p_cols = x_full.shape
    rank = np.linalg.matrix_rank(x_full)
    if rank == p_cols:
        return
    culprits = []
    for c in covariates:
        others = np.column_stack([np.ones(n)] + [p[2] for p in parts if p[0] != c])
        if np.linalg.matrix_rank(others) == rank:
            culprits.append(c)
    what = (
        f"covariate(s) {', '.join(map(repr, culprits))} are"
        if culprits
        else "the design columns are"
    )
    raise DesignError(
        f"{what} linearly dependent on the factors or other covariates "
        "(e.g. constant within every cell); drop them from the covariates"
    )


def _effect_rows(
    parts: list[Part], y: np.ndarray, *, sse: float, df_resid: int, ss_type: int
) -> list[dict[str, float | str]]:
    """One F test per term: type III (or II) SS against the full model's SSE."""
    n = len(y)
    mse = sse / df_resid
    rows: list[dict[str, float | str]] = []
    for name, term, block in parts:
        if ss_type == 3 or term is None:
            reduced = [p[2] for p in parts if p[0] != name]
            ss = _sse(np.column_stack([np.ones(n), *reduced]), y) - sse
        else:
            base = [p[2] for p in parts if p[1] is None or not set(term) <= set(p[1])]
            x0 = np.column_stack([np.ones(n), *base])
            ss = _sse(x0, y) - _sse(np.column_stack([x0, block]), y)
        ss = max(ss, 0.0)
        df1 = block.shape[1]
        f = (ss / df1) / mse if mse > 0 else np.inf
        rows.append(
            {
                "effect": name,
                "df1": float(df1),
                "df2": float(df_resid),
                "F": float(f),
                "p": float(special.fdtrc(df1, df_resid, f)),
                "np2": ss / (ss + sse) if ss + sse > 0 else np.nan,
                "SS": ss,
            }
        )
    return rows


def covariate_anova(
    data: pd.DataFrame,
    *,
    dv: str,
    subject: str,
    within: Sequence[str],
    covariates: Sequence[str],
    drop_incomplete: bool = False,
    ss_type: int = 3,
) -> FactorialAnovaResult:
    """The paper's analysis of a within-subjects design: one row per subject and cell
    (repeated rows averaged, covariates too), then :func:`factorial_anova` with covariates.

    Subjects enter only through their covariates (as in the paper: residual df =
    N - cells - covariates); incomplete subjects raise DesignError unless dropped.
    """

    roles = [dv, subject, *within, *covariates]
    dupes = sorted({n for n in roles if roles.count(n) > 1})
    if dupes:
        raise DesignError(
            f"column(s) {', '.join(map(repr, dupes))} given in two roles (dependent "
            "variable, subject, factor, covariate); each role needs its own column"
        )
    cells = cell_means(data, dv=dv, subject=subject, within=within, drop_incomplete=drop_incomplete)
    require_columns(data, list(covariates))
    d = pd.DataFrame({subject: data[subject].astype(str)})
    for f in within:
        d[f] = data[f].astype(str)
    for c in [dv, *covariates]:
        d[c] = numeric_column(data, c)
    d = d[d[subject].isin(set(cells.subjects)) & d[dv].notna()]
    agg = d.groupby([subject, *within], sort=False, as_index=False)[[dv, *covariates]].mean()
    for f, lv in zip(within, cells.levels, strict=True):
        agg[f] = pd.Categorical(agg[f], categories=list(lv))
    res = factorial_anova(agg, dv=dv, factors=within, covariates=covariates, ss_type=ss_type)
    return replace(res, notes=cells.notes + res.notes)

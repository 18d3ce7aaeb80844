"""Repeated-measures (within-subjects) ANOVA on cell means, any number of factors and levels.

For effect ``E`` with orthonormal contrast matrix ``K_E`` (Kronecker product of Helmert contrasts
for the factors in ``E`` and normalised averaging vectors for the rest), each subject's scores
``z_s = K_E' y_s`` give ``SS_E = n ||mean z||^2`` and ``SS_ExS = sum_s ||z_s - mean z||^2``;
``F = (SS_E / df_E) / (SS_ExS / (df_E (n - 1)))`` - the classical univariate (sphericity-assumed)
test, identical to the textbook ``SS_E`` vs ``SS_{E x subject}`` decomposition. Partial eta
squared ``np2 = SS_E / (SS_E + SS_ExS)``; Greenhouse-Geisser epsilon from the covariance of ``z``
(``eps = tr(S)^2 / (df_E tr(S^2))``, 1 for one-degree-of-freedom effects).

Sphericity, for effects with ``df_E = k > 1``: Mauchly's ``W = det(S) / (tr(S) / k)^k`` with
``chi2 = -(n - 1 - (2k^2 + k + 2) / (6k)) ln W`` on ``k(k+1)/2 - 1`` df; Huynh-Feldt epsilon
``eps_HF = min(1, (n k eps_GG - 2) / (k (n - 1 - k eps_GG)))`` (one group of subjects, as R's
``car`` and pingouin compute it). GG- and HF-corrected p multiply both df by epsilon.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import special

from analysis.design import CellData, cell_means, effect_name, effect_terms

COLUMNS = [
    "effect",
    "df1",
    "df2",
    "F",
    "p",
    "np2",
    "SS",
    "SS_error",
    "eps_gg",
    "p_gg",
    "eps_hf",
    "p_hf",
    "mauchly_W",
    "mauchly_chi2",
    "mauchly_df",
    "mauchly_p",
]


@dataclass(frozen=True)
class RMAnovaResult:
    """``table`` has one row per effect (columns ``COLUMNS``); ``notes`` what was done to the data."""

    table: pd.DataFrame
    n_subjects: int
    notes: tuple[str, ...]
    cells: CellData


def helmert(k: int) -> np.ndarray:
    """``k x (k-1)`` orthonormal contrasts, each column orthogonal to the constant vector."""
    h = np.zeros((k, k - 1))
    for j in range(1, k):
        h[:j, j - 1] = 1.0
        h[j, j - 1] = -float(j)
        h[:, j - 1] /= np.linalg.norm(h[:, j - 1])
    return h


def effect_contrasts(n_levels: Sequence[int], term: Sequence[int]) -> np.ndarray:
    """Orthonormal contrast matrix of one effect over cells in product order."""
    k = np.ones((1, 1))
    for i, n in enumerate(n_levels):
        m = helmert(n) if i in term else np.full((n, 1), 1.0 / np.sqrt(n))
        k = np.kron(k, m)
    return k


def sphericity(z_resid: np.ndarray, *, df: int | None = None) -> dict[str, float]:
    """GG and HF epsilon and Mauchly's test from centred contrast scores ``(n, k)``.

    ``df``: the scores' error df (default ``n - 1``, one group; ``n - g`` for scores centred
    within ``g`` groups of subjects, where HF is Lecoutre's ``((df + 1) k eps - 2) /
    (k (df - k eps))`` as R's ``car`` computes it, and Mauchly's chi2 uses ``df`` for ``n - 1``).
    """
    n, k = z_resid.shape
    dfe = n - 1 if df is None else int(df)
    nan = float("nan")
    if k == 1:
        return {
            "eps_gg": 1.0,
            "eps_hf": 1.0,
            "mauchly_W": nan,
            "mauchly_chi2": nan,
            "mauchly_df": nan,
            "mauchly_p": nan,
        }
    s = z_resid.T @ z_resid / dfe
    tr, tr2 = float(np.trace(s)), float(np.trace(s @ s))
    eps = min(1.0, max(tr * tr / (k * tr2), 1.0 / k)) if tr2 > 0 else 1.0
    hf_den = k * (dfe - k * eps)
    eps_hf = min(1.0, ((dfe + 1) * k * eps - 2) / hf_den) if hf_den > 0 else 1.0
    eps_hf = max(eps_hf, eps)
    out = {
        "eps_gg": eps,
        "eps_hf": eps_hf,
        "mauchly_W": nan,
        "mauchly_chi2": nan,
        "mauchly_df": float(k * (k + 1) // 2 - 1),
        "mauchly_p": nan,
    }
    if dfe >= k and tr > 0:  # W needs a non-singular S (more error df than contrasts)
        sign, logdet = np.linalg.slogdet(s)
        log_w = logdet - k * np.log(tr / k) if sign > 0 else -np.inf
        chi2 = -(dfe - (2 * k * k + k + 2) / (6 * k)) * log_w
        out.update(
            mauchly_W=float(np.exp(log_w)),
            mauchly_chi2=float(chi2),
            mauchly_p=float(special.chdtrc(out["mauchly_df"], chi2)),
        )
    return out


def rm_anova_cells(cells: CellData) -> pd.DataFrame:
    """The ANOVA table of complete cell means (see the module docstring)."""
    y = cells.values
    n = y.shape[0]
    n_levels = [len(lv) for lv in cells.levels]
    rows = []
    for term in effect_terms(cells.factors):
        z = y @ effect_contrasts(n_levels, term)
        df1 = z.shape[1]
        zbar = z.mean(axis=0)
        ss = float(n * zbar @ zbar)
        resid = z - zbar
        ss_err = float((resid**2).sum())
        df2 = df1 * (n - 1)
        f = (ss / df1) / (ss_err / df2) if ss_err > 0 else np.inf
        p = float(special.fdtrc(df1, df2, f)) if np.isfinite(f) else 0.0
        sph = sphericity(resid)

        def corrected(eps: float, f: float = f, df1: int = df1, df2: int = df2) -> float:
            return float(special.fdtrc(df1 * eps, df2 * eps, f)) if np.isfinite(f) else 0.0

        total = ss + ss_err
        rows.append(
            {
                "effect": effect_name(cells.factors, term),
                "df1": float(df1),
                "df2": float(df2),
                "F": float(f),
                "p": p,
                "np2": ss / total if total > 0 else np.nan,
                "SS": ss,
                "SS_error": ss_err,
                "eps_gg": sph["eps_gg"],
                "p_gg": corrected(sph["eps_gg"]),
                "eps_hf": sph["eps_hf"],
                "p_hf": corrected(sph["eps_hf"]),
                "mauchly_W": sph["mauchly_W"],
                "mauchly_chi2": sph["mauchly_chi2"],
                "mauchly_df": sph["mauchly_df"],
                "mauchly_p": sph["mauchly_p"],
            }
        )
    return pd.DataFrame(rows, columns=COLUMNS)


def rm_anova(
    data: pd.DataFrame,
    *,
    dv: str,
    subject: str,
    within: Sequence[str],
    drop_incomplete: bool = False,
) -> RMAnovaResult:
    """Repeated-measures ANOVA of ``dv`` on the ``within`` factors of long-format ``data``.

    Repeated rows per subject and cell are averaged; incomplete subjects raise DesignError
    (or are dropped with ``drop_incomplete=True``). With ``n`` subjects a one-df effect is
    tested on ``F(1, n - 1)``.
    """
    cells = cell_means(data, dv=dv, subject=subject, within=within, drop_incomplete=drop_incomplete)
    return RMAnovaResult(
        table=rm_anova_cells(cells),
        n_subjects=len(cells.subjects),
        notes=cells.notes,
        cells=cells,
    )

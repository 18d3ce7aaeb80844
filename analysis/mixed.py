"""Linear mixed model with a random intercept per subject, type III F tests, Satterthwaite df.

Model: ``y_ij = x_ij' b + u_i + e_ij`` with ``u_i ~ N(0, s_u^2)``, ``e_ij ~ N(0, s_e^2)``, i.e.
``V = s_e^2 I + s_u^2 Z Z'``; factors in sum-to-zero coding with all interactions, covariates
centred. The variance components are estimated by REML as lme4 does: the residual variance is
profiled out exactly and the profiled likelihood maximised over ``gamma = s_u^2 / s_e^2 >= 0``,
with the boundary ``gamma = 0`` compared as a candidate of its own (there the fit is OLS
exactly, on ``n - p`` df); the fixed effects are then the GLS estimate ``b = C X'V^-1 y``,
``C = (X'V^-1 X)^-1``.

Each effect with hypothesis matrix ``L`` (``q`` rows) is tested with the Wald F
``F = b'L'(L C L')^-1 L b / q`` on Satterthwaite's denominator df (the method of SAS PROC MIXED
``ddfm=satterthwaite`` and R's lmerTest): for one contrast ``l``,
``df = 2 (l'Cl)^2 / (g' A g)`` with ``g = d(l'C(theta)l)/d theta`` and ``A`` the inverse of the
REML information at ``theta = (s_u^2, s_e^2)``; for ``q > 1`` each eigen-contrast of ``L C L'``
gets its ``nu_m`` and ``df2 = 2E / (E - q)``, ``E = sum nu_m / (nu_m - 2)`` (Fai & Cornelius
1996; 2 when any ``nu_m <= 2``). In a balanced design this reproduces the classical F tests: a
within-subject effect on the pooled ``(n-1)(cells-1)`` error df, a subject-level covariate on
``n - 1 - k`` df for ``k`` subject-level terms.

Everything uses per-subject sums (``V^-1`` of a random-intercept block is
``(I - c_i J) / s_e^2`` with ``c_i = s_u^2 / (s_e^2 + n_i s_u^2)``), so the cost is linear in the
number of rows.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import optimize, special

from analysis.anova import factor_blocks
from analysis.design import effect_name, effect_terms, numeric_column, require_columns
from analysis.errors import DesignError

DF_METHOD = "Satterthwaite"
METHOD = (
    "linear mixed model, random intercept per subject (REML, residual variance profiled); "
    "type III Wald F, Satterthwaite df"
)
COLUMNS = ["effect", "df1", "df2", "F", "p", "np2", "method"]
ESTIMATE_COLUMNS = ["term", "contrast", "estimate", "se", "df", "t", "p", "ci_low", "ci_high"]


@dataclass(frozen=True)
class MixedModelResult:
    """``table``: one F test per effect and covariate (``np2`` = ``F df1 / (F df1 + df2)``);
    ``estimates``: each main-effect level against the first level (unweighted marginal means)
    and each covariate's slope, with Satterthwaite t, df and 95% CI."""

    table: pd.DataFrame
    estimates: pd.DataFrame
    var_subject: float
    var_resid: float
    n: int
    n_subjects: int
    levels: dict[str, tuple[str, ...]]
    notes: tuple[str, ...] = ()
    df_method: str = DF_METHOD

    @property
    def icc(self) -> float:
        """Intraclass correlation ``s_u^2 / (s_u^2 + s_e^2)``."""
        total = self.var_subject + self.var_resid
        return self.var_subject / total if total > 0 else float("nan")


@dataclass(frozen=True)
class _Stats:
    """Sufficient statistics: ``X'X, X'y, y'y`` and per-subject column sums and sizes."""

    xtx: np.ndarray
    xty: np.ndarray
    yty: float
    sx: np.ndarray  # (m, p) per-subject sums of X
    sy: np.ndarray  # (m,) per-subject sums of y
    n_i: np.ndarray  # (m,) rows per subject
    n: int

    @classmethod
    def of(cls, x: np.ndarray, y: np.ndarray, groups: np.ndarray) -> _Stats:
        m = int(groups.max()) + 1
        sx = np.zeros((m, x.shape[1]))
        np.add.at(sx, groups, x)
        sy = np.bincount(groups, weights=y, minlength=m)
        n_i = np.bincount(groups, minlength=m).astype(float)
        return cls(x.T @ x, x.T @ y, float(y @ y), sx, sy, n_i, len(y))

    def gls(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """``(C, b, REML log-likelihood)`` at ``theta = (s_u^2, s_e^2)``."""
        su2, se2 = float(theta[0]), float(theta[1])
        c = su2 / (se2 + self.n_i * su2)
        xwx = (self.xtx - (self.sx * c[:, None]).T @ self.sx) / se2
        xwy = (self.xty - self.sx.T @ (c * self.sy)) / se2
        ywy = (self.yty - float(c @ self.sy**2)) / se2
        cov = np.linalg.inv(xwx)
        b = cov @ xwy
        rwr = ywy - float(b @ xwy)
        logdet_v = float(self.n * np.log(se2) + np.log1p(self.n_i * su2 / se2).sum())
        logdet_xwx = float(np.linalg.slogdet(xwx)[1])
        p = len(b)
        ll = -0.5 * (logdet_v + logdet_xwx + rwr + (self.n - p) * np.log(2 * np.pi))
        return cov, b, ll


def _steps(theta: np.ndarray) -> np.ndarray:
    scale = max(float(theta.sum()), 1e-12)
    return np.array([1e-4 * scale, 1e-4 * scale])


def _theta_covariance(stats: _Stats, theta: np.ndarray) -> np.ndarray:
    """``A``: inverse of the observed REML information (numerical Hessian of ``-ll``)."""
    h = _steps(theta)

    def ll(t: np.ndarray) -> float:
        return stats.gls(t)[2]

    hess = np.zeros((2, 2))
    for i, j in itertools.product(range(2), repeat=2):
        ei, ej = np.eye(2)[i] * h[i], np.eye(2)[j] * h[j]
        hess[i, j] = (
            ll(theta + ei + ej) - ll(theta + ei - ej) - ll(theta - ei + ej) + ll(theta - ei - ej)
        ) / (4 * h[i] * h[j])
    info = -hess
    if theta[0] <= 1e-10 * max(theta[1], 1e-300) or np.linalg.eigvalsh(info).min() <= 0:
        # s_u^2 on its boundary: only the residual variance is free
        out = np.zeros((2, 2))
        out[1, 1] = 1.0 / info[1, 1] if info[1, 1] > 0 else 0.0
        return out
    return np.linalg.inv(info)


def _boundary_derivatives(
    stats: _Stats, theta: np.ndarray, cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(A, dC/d theta)`` on the boundary ``s_u^2 = 0``, exactly: only ``s_e^2`` is free, its
    REML information is ``(n - p) / (2 s_e^4)`` and ``C = s_e^2 (X'X)^-1`` gives
    ``dC/ds_e^2 = C / s_e^2``; every Satterthwaite df is then ``n - p``, OLS's residual df."""
    se2 = float(theta[1])
    a = np.zeros((2, 2))
    a[1, 1] = 2.0 * se2**2 / (stats.n - cov.shape[0])
    dcov = np.zeros((2, *cov.shape))
    dcov[1] = cov / se2
    return a, dcov


def _cov_gradient(stats: _Stats, theta: np.ndarray) -> np.ndarray:
    """``dC/d theta_k`` by central differences, shape ``(2, p, p)``."""
    h = _steps(theta)
    out = []
    for k in range(2):
        e = np.eye(2)[k] * h[k]
        out.append((stats.gls(theta + e)[0] - stats.gls(theta - e)[0]) / (2 * h[k]))
    return np.array(out)


def satterthwaite_df(
    contrasts: np.ndarray, cov: np.ndarray, dcov: np.ndarray, a: np.ndarray
) -> float:
    """Denominator df of the F test of ``L b = 0`` (see the module docstring)."""
    lcl = contrasts @ cov @ contrasts.T
    vals, vecs = np.linalg.eigh(lcl)
    rows = vecs.T @ contrasts
    nus = []
    for v, row in zip(vals, rows, strict=True):
        g = np.array([row @ dc @ row for dc in dcov])
        var = float(g @ a @ g)
        nus.append(2 * v * v / var if var > 0 else np.inf)
    nu = np.array(nus)
    if len(nu) == 1 or np.allclose(nu, nu[0], rtol=1e-8):
        return float(nu[0])
    if (nu <= 2).any():
        return 2.0
    e = float((nu / (nu - 2)).sum())
    return 2 * e / (e - len(nu))


def _design(
    data: pd.DataFrame, factors: Sequence[str], covariates: Sequence[str]
) -> tuple[np.ndarray, list[tuple[str, slice]], dict[str, tuple[str, ...]]]:
    levels, blocks = factor_blocks(data, factors)
    cols = [np.ones((len(data), 1))]
    spans: list[tuple[str, slice]] = []
    start = 1
    for t in effect_terms(factors):
        cols.append(blocks[t])
        spans.append((effect_name(factors, t), slice(start, start + blocks[t].shape[1])))
        start += blocks[t].shape[1]
    for c in covariates:
        v = numeric_column(data, c).to_numpy()
        if np.ptp(v) == 0:
            raise DesignError(f"covariate {c!r} is constant; drop it from the covariates")
        cols.append((v - v.mean())[:, None])
        spans.append((c, slice(start, start + 1)))
        start += 1
    return np.column_stack(cols), spans, levels


BOUNDARY_TOL = 1e-9
"""An interior optimum must beat the boundary's REML log-likelihood by more than this (a gain
at rounding level is no evidence of subject variance)."""
GAMMA_GRID = np.concatenate([[0.0], np.logspace(-8, 4, 49)])
"""Variance ratios ``gamma = s_u^2 / s_e^2`` searched first (0 is the boundary)."""


def profiled_reml(stats: _Stats, gamma: float) -> tuple[float, np.ndarray]:
    """The REML log-likelihood with ``s_e^2`` profiled out, and ``theta = (s_u^2, s_e^2)``, at
    ``gamma = s_u^2 / s_e^2``: ``s_e^2 = r'V_g^-1 r / (n - p)`` with ``V_g = I + gamma Z Z'``,
    exactly (at ``gamma = 0``: the OLS residual variance ``RSS / (n - p)``)."""
    _, b, _ = stats.gls(np.array([gamma, 1.0]))
    su2, se2 = float(gamma), 1.0
    c = su2 / (se2 + stats.n_i * su2)
    xwy = stats.xty - stats.sx.T @ (c * stats.sy)
    rwr = stats.yty - float(c @ stats.sy**2) - float(b @ xwy)
    se2 = max(rwr, 0.0) / (stats.n - len(b))
    if se2 <= 0:
        return -np.inf, np.array([0.0, 0.0])
    theta = np.array([gamma * se2, se2])
    return stats.gls(theta)[2], theta


def _fit_variances(stats: _Stats) -> tuple[np.ndarray, list[str]]:
    """REML ``(s_u^2, s_e^2)``, the way lme4 fits it: ``s_e^2`` profiled out exactly
    (:func:`profiled_reml`) and the profiled likelihood maximised over ``gamma >= 0`` -- a
    grid over ``0`` and ``1e-8..1e4``, then Brent's method on ``log gamma`` around the best
    interior point. The boundary ``gamma = 0`` is one candidate of its own, compared by its
    profiled likelihood: when it wins, the fit is OLS exactly (``s_e^2 = RSS / (n - p)``), not
    an optimiser's approach to it."""
    grid = [(profiled_reml(stats, g)[0], g) for g in GAMMA_GRID]
    best_ll, best_g = max(grid, key=lambda t: t[0])
    candidates = [(grid[0][0], 0.0), (best_ll, best_g)]
    k = int(np.argmax([ll for ll, _ in grid]))
    if k > 0:  # refine between the grid neighbours of the best interior point
        lo = np.log(GAMMA_GRID[max(k - 1, 1)])
        hi = np.log(GAMMA_GRID[min(k + 1, len(GAMMA_GRID) - 1)])
        found = optimize.minimize_scalar(
            lambda u: -profiled_reml(stats, float(np.exp(u)))[0],
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-10},
        )
        g = float(np.exp(found.x))
        candidates.append((profiled_reml(stats, g)[0], g))
    ll, gamma = max(candidates, key=lambda t: t[0])
    if ll - candidates[0][0] <= BOUNDARY_TOL:  # no real gain inside: the exact OLS answer
        gamma = 0.0
    _, theta = profiled_reml(stats, gamma)
    notes = []
    if gamma == 0.0:
        notes.append(
            "the subject variance is estimated at zero (REML boundary): the tests "
            "reduce to ordinary least squares on N - p df"
        )
    return theta, notes


def mixed_anova(
    data: pd.DataFrame,
    *,
    dv: str,
    subject: str,
    factors: Sequence[str],
    covariates: Sequence[str] = (),
) -> MixedModelResult:
    """Fit the random-intercept model to every row of ``data`` (repeated rows per subject and
    cell are fine; cells need not be complete) and test each effect (see the module doc)."""
    factors, covariates = list(factors), list(covariates)
    names = [dv, subject, *factors, *covariates]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DesignError(
            f"column(s) {', '.join(map(repr, dupes))} given in two roles; each "
            "role needs its own column"
        )
    if not factors and not covariates:
        raise DesignError("no factor or covariate given; name at least one")
    require_columns(data, names)
    d, y, notes = _complete_rows(
        data, dv=dv, subject=subject, factors=factors, covariates=covariates
    )
    subjects, groups = np.unique(d[subject].astype(str).to_numpy(), return_inverse=True)
    if len(subjects) < 3:
        raise DesignError(
            f"{len(subjects)} subject(s) with data; a random-intercept model needs at least three"
        )
    x, spans, levels = _design(d, factors, covariates)
    p = x.shape[1]
    if len(y) <= p + 1 or np.linalg.matrix_rank(x) < p:
        raise DesignError(
            f"{len(y)} rows cannot identify {p} fixed effects (empty cells, or a "
            "covariate that is a function of the factors); collect more data or "
            "drop terms"
        )
    stats = _Stats.of(x, y, groups)
    theta, fit_notes = _fit_variances(stats)
    cov, b, _ = stats.gls(theta)
    if theta[0] == 0.0:
        a, dcov = _boundary_derivatives(stats, theta, cov)
    else:
        a, dcov = _theta_covariance(stats, theta), _cov_gradient(stats, theta)
    fit = _Fit(b=b, cov=cov, dcov=dcov, a=a)
    contrasts = _contrasts(levels, spans, n_terms=len(effect_terms(factors)), p=p)
    return MixedModelResult(
        table=pd.DataFrame([fit.f_test(name, sl) for name, sl in spans], columns=COLUMNS),
        estimates=pd.DataFrame(
            [fit.estimate(t, c, v) for t, c, v in contrasts], columns=ESTIMATE_COLUMNS
        ),
        var_subject=float(theta[0]),
        var_resid=float(theta[1]),
        n=len(y),
        n_subjects=len(subjects),
        levels=levels,
        notes=tuple(notes + fit_notes),
    )


def _complete_rows(
    data: pd.DataFrame, *, dv: str, subject: str, factors: list[str], covariates: list[str]
) -> tuple[pd.DataFrame, np.ndarray, list[str]]:
    """The rows with every value present (renumbered), their ``y``, and a note on the rest."""
    y = numeric_column(data, dv).to_numpy()
    keep = ~np.isnan(y) & data[subject].notna().to_numpy()
    for c in covariates:
        keep &= ~np.isnan(numeric_column(data, c).to_numpy())
    for f in factors:
        keep &= data[f].notna().to_numpy()
    notes = [] if keep.all() else [f"{int((~keep).sum())} row(s) with missing values were left out"]
    return data.loc[keep].reset_index(drop=True), y[keep], notes


@dataclass(frozen=True)
class _Fit:
    """The fixed effects ``b``, their covariance, its gradient in the variances and the
    variances' covariance ``a``: what a Wald test with Satterthwaite df needs."""

    b: np.ndarray
    cov: np.ndarray
    dcov: np.ndarray
    a: np.ndarray

    def f_test(self, name: str, sl: slice) -> dict[str, float | str]:
        """Wald F of the coefficients ``sl`` (one effect) on Satterthwaite df."""
        lmat = np.eye(len(self.b))[sl]
        lb = lmat @ self.b
        q = lmat.shape[0]
        f = float(lb @ np.linalg.solve(lmat @ self.cov @ lmat.T, lb) / q)
        df2 = satterthwaite_df(lmat, self.cov, self.dcov, self.a)
        return {
            "effect": name,
            "df1": float(q),
            "df2": df2,
            "F": f,
            "p": float(special.fdtrc(q, df2, f)),
            "np2": f * q / (f * q + df2),
            "method": f"LMM random intercept, {DF_METHOD} df",
        }

    def estimate(self, term: str, contrast: str, v: np.ndarray) -> dict[str, float | str]:
        """The contrast ``v @ b`` with its SE, Satterthwaite t and 95% CI."""
        e, se = float(v @ self.b), float(np.sqrt(v @ self.cov @ v))
        df = satterthwaite_df(v[None, :], self.cov, self.dcov, self.a)
        t = e / se if se > 0 else np.nan
        half = float(special.stdtrit(df, 0.975) * se)
        return {
            "term": term,
            "contrast": contrast,
            "estimate": e,
            "se": se,
            "df": df,
            "t": t,
            "p": float(2 * special.stdtr(df, -abs(t))),
            "ci_low": e - half,
            "ci_high": e + half,
        }


def _contrasts(
    levels: dict[str, tuple[str, ...]],
    spans: list[tuple[str, slice]],
    *,
    n_terms: int,
    p: int,
) -> list[tuple[str, str, np.ndarray]]:
    """Each factor level minus the first (differences of unweighted marginal means under the
    sum-to-zero coding), then each covariate's slope, as coefficient vectors."""
    est = []
    for i, (f, lv) in enumerate(levels.items()):
        sl = spans[i][1]
        k = len(lv)

        def level_vector(j: int, k: int = k, sl: slice = sl) -> np.ndarray:
            v = np.zeros(p)
            if j < k - 1:
                v[sl.start + j] = 1.0
            else:
                v[sl] = -1.0
            return v

        for j in range(1, k):
            est.append((f, f"{lv[j]} - {lv[0]}", level_vector(j) - level_vector(0)))
    for name, sl in spans[n_terms:]:
        v = np.zeros(p)
        v[sl] = 1.0
        est.append((name, "slope", v))
    return est

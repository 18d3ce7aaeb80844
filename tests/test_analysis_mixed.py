"""The random-intercept mixed model against identities that must hold: in a balanced design its
within-subject F tests are the randomised-block F tests on the pooled (n-1)(cells-1) error df,
a subject-level covariate is the regression of subject means on n - 2 df; its estimates are
statsmodels MixedLM's; and the command line's --mixed option."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
import statsmodels.formula.api as smf
from scipy import stats
from statsmodels.regression.mixed_linear_model import MixedLM

from analysis.__main__ import main as analysis_main
from analysis.errors import DesignError
from analysis.mixed import _fit_variances, _Stats, mixed_anova, profiled_reml, satterthwaite_df
from tests.support.cli import run_main

ROOT = Path(__file__).resolve().parents[1]


def _balanced(n: int = 10, seed: int = 0) -> pd.DataFrame:
    """``n`` subjects x a (3 levels) x b (2 levels), a subject-level covariate z."""
    rng = np.random.default_rng(seed)
    rows = []
    for s in range(n):
        u, z = rng.normal(0, 2), rng.normal(10, 2)
        for a, b in itertools.product(["a1", "a2", "a3"], ["b1", "b2"]):
            y = u + 0.4 * z + 0.8 * (a == "a2") + 0.5 * (b == "b2") + rng.normal()
            rows.append({"sub": f"s{s}", "a": a, "b": b, "z": z, "y": y})
    return pd.DataFrame(rows)


def _block_f(d: pd.DataFrame, factor: str) -> tuple[float, int]:
    """F of a main effect in the randomised-block ANOVA (subjects as blocks, pooled error)."""
    n, cells = d["sub"].nunique(), d.groupby(["a", "b"]).ngroups
    y, gm = d["y"].to_numpy(), d["y"].mean()
    ss_tot = ((y - gm) ** 2).sum()
    ss_sub = cells * ((d.groupby("sub")["y"].mean() - gm) ** 2).sum()
    ss_cells = n * ((d.groupby(["a", "b"])["y"].mean() - gm) ** 2).sum()
    df_err = (n - 1) * (cells - 1)
    m = d.groupby(factor)["y"].mean()
    ss_f = len(d) / len(m) * ((m - gm) ** 2).sum()
    return (ss_f / (len(m) - 1)) / ((ss_tot - ss_sub - ss_cells) / df_err), df_err


def test_balanced_within_effects_are_the_randomised_block_f_tests() -> None:
    d = _balanced()
    res = mixed_anova(d, dv="y", subject="sub", factors=["a", "b"]).table.set_index("effect")
    for f in ("a", "b"):
        f_ref, df_ref = _block_f(d, f)
        assert res.loc[f, "F"] == pytest.approx(f_ref, rel=1e-4)
        assert res.loc[f, "df2"] == pytest.approx(df_ref, rel=1e-3)  # 9 x 5 = 45
    assert res.loc["a", "df1"] == 2 and res.loc["a:b", "df2"] == pytest.approx(45, rel=1e-3)
    assert (res["method"].str.contains("Satterthwaite")).all()


def test_subject_level_covariate_is_the_regression_of_subject_means() -> None:
    d = _balanced(n=9, seed=3)
    res = mixed_anova(d, dv="y", subject="sub", factors=["a", "b"], covariates=["z"])
    row = res.table.set_index("effect").loc["z"]
    means = d.groupby("sub")[["y", "z"]].mean()
    ols = sm.OLS(means["y"], sm.add_constant(means["z"])).fit()
    assert row["df2"] == pytest.approx(9 - 2, rel=1e-3)
    assert row["F"] == pytest.approx(ols.fvalue, rel=1e-4)
    slope = res.estimates.set_index("term").loc["z"]
    assert slope["estimate"] == pytest.approx(ols.params["z"], rel=1e-5)
    assert slope["df"] == pytest.approx(7, rel=1e-3)
    # within effects keep their pooled df, covariate or not
    assert res.table.set_index("effect").loc["b", "df2"] == pytest.approx(8 * 5, rel=1e-3)


def test_estimates_match_statsmodels_mixedlm_on_unbalanced_data() -> None:
    """Same model in dummy coding: the same REML variances, covariate slope and its SE."""
    d = _balanced(n=8, seed=5)
    d = d.drop(index=[1, 7, 8, 20, 33]).reset_index(drop=True)
    d = pd.concat([d, d.iloc[:3].assign(y=d["y"].iloc[:3] + 0.3)], ignore_index=True)
    res = mixed_anova(d, dv="y", subject="sub", factors=["a", "b"], covariates=["z"])
    dummies = pd.get_dummies(d[["a", "b"]], drop_first=True).astype(float)
    inter = dummies.filter(like="a_").mul(dummies["b_b2"], axis=0).add_suffix(":b")
    x = sm.add_constant(pd.concat([dummies, inter], axis=1).assign(z=d["z"]))
    fit = MixedLM(d["y"].to_numpy(), x.to_numpy(), groups=d["sub"].to_numpy()).fit(reml=True)
    assert res.n == len(d) and res.n_subjects == 8
    assert res.var_subject == pytest.approx(float(np.asarray(fit.cov_re)[0, 0]), rel=1e-3)
    assert res.var_resid == pytest.approx(fit.scale, rel=1e-3)
    zi = list(x.columns).index("z")
    slope = res.estimates.set_index("term").loc["z"]
    assert slope["estimate"] == pytest.approx(fit.fe_params[zi], rel=1e-4)
    assert slope["se"] == pytest.approx(fit.bse_fe[zi], rel=1e-3)
    # unbalanced: the covariate's df lies between the subject-level and the pooled df
    assert 8 - 2 - 0.5 < slope["df"] < len(d) - 12


def test_satterthwaite_of_one_contrast_is_the_welch_style_formula() -> None:
    """q = 1: df = 2 (l'Cl)^2 / (g'Ag); q > 1 with equal nu returns that nu."""
    cov = np.diag([2.0, 3.0])
    dcov = np.array([np.diag([1.0, 0.0]), np.diag([0.0, 1.0])])
    a = np.diag([0.5, 0.25])
    l1 = np.array([[1.0, 0.0]])
    assert satterthwaite_df(l1, cov, dcov, a) == pytest.approx(2 * 4 / 0.5)
    cov2, dcov2 = np.eye(2), np.array([np.eye(2), np.zeros((2, 2))])
    assert satterthwaite_df(np.eye(2), cov2, dcov2, np.eye(2)) == pytest.approx(2.0)
    nus = satterthwaite_df(
        np.eye(2),
        np.diag([1.0, 2.0]),
        np.array([np.diag([1.0, 1.0]), np.zeros((2, 2))]),
        np.diag([0.1, 0.0]),
    )
    e = 20 / 18 + 80 / 78  # nu = 2 v^2 / (0.1 g^2): 20 and 80
    assert nus == pytest.approx(2 * e / (e - 2))


def test_within_effect_p_matches_f_distribution_and_errors_are_typed() -> None:
    d = _balanced(n=6, seed=9)
    t = mixed_anova(d, dv="y", subject="sub", factors=["b"]).table.iloc[0]
    assert t["p"] == pytest.approx(stats.f.sf(t["F"], t["df1"], t["df2"]))
    with pytest.raises(DesignError, match="at least three"):
        mixed_anova(d[d["sub"].isin(["s0", "s1"])], dv="y", subject="sub", factors=["a"])
    with pytest.raises(DesignError, match="two roles"):
        mixed_anova(d, dv="y", subject="sub", factors=["a"], covariates=["a"])
    with pytest.raises(DesignError, match="constant"):
        mixed_anova(d.assign(c=1.0), dv="y", subject="sub", factors=["a"], covariates=["c"])


def test_cli_mixed_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _balanced(n=8, seed=2)
    path = tmp_path / "long.csv"
    d.to_csv(path, index=False)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "analysis",
            "anova",
            "--csv",
            str(path),
            "--dv",
            "y",
            "--subject",
            "sub",
            "--within",
            "a",
            "b",
            "--covariates",
            "z",
            "--mixed",
            "--format",
            "json",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    rows = {r["effect"]: r for r in json.loads(proc.stdout)}
    assert set(rows) == {"a", "b", "a:b", "z"}
    assert rows["z"]["df2"] == pytest.approx(6, rel=1e-3)
    assert "Satterthwaite" in proc.stderr
    # the same command line's main here: --mixed with another model is refused in one line
    argv = ["anova", "--csv", str(path), "--dv", "y", "--subject", "sub", "--within", "a"]
    bad = run_main(analysis_main, [*argv, "--mixed", "--model", "factorial"], capsys)
    assert bad.returncode == 2 and "--mixed" in bad.stderr


def _boundary_data() -> pd.DataFrame:
    """Subject means removed: REML puts s_u^2 on its boundary."""
    rng = np.random.default_rng(1)
    d = pd.DataFrame(
        [
            {"sub": f"s{s}", "a": a, "y": rng.normal() + 0.3 * (a == "y")}
            for s in range(6)
            for a in ("x", "y")
            for _ in range(3)
        ]
    )
    d["y"] -= d.groupby("sub")["y"].transform("mean")
    return d


def test_zero_subject_variance_is_lme4s_answer_exactly() -> None:
    """At the boundary lme4 (which profiles the residual variance out) returns the OLS residual
    variance RSS / (n - p), and lmerTest's Satterthwaite df are then the integer n - p: the fit
    must land on that answer, not stop 2e-6 short of it (df 34.0000025 before the fix)."""
    d = _boundary_data()
    res = mixed_anova(d, dv="y", subject="sub", factors=["a"])
    ols = smf.ols("y ~ C(a, Sum)", data=d).fit()
    n, p = len(d), 2
    assert res.var_subject == 0.0
    assert res.var_resid == pytest.approx(ols.ssr / (n - p), rel=1e-9, abs=0)
    row = res.table.iloc[0]
    assert row["df2"] == pytest.approx(n - p, rel=0, abs=1e-9)
    assert row["F"] == pytest.approx(ols.fvalue, rel=1e-9, abs=0)
    assert row["p"] == pytest.approx(ols.f_pvalue, rel=1e-9, abs=0)
    est = res.estimates.iloc[0]
    assert est["df"] == pytest.approx(n - p, rel=0, abs=1e-9)
    assert abs(est["t"]) == pytest.approx(np.sqrt(ols.fvalue), rel=1e-9, abs=0)
    assert any("boundary" in n for n in res.notes)


DYESTUFF2 = [
    [7.298, 3.846, 2.434, 9.566, 7.990],
    [5.220, 6.556, 0.608, 11.788, -0.892],
    [0.110, 10.386, 13.434, 5.510, 8.166],
    [2.212, 4.852, 7.092, 9.288, 4.980],
    [0.282, 9.014, 4.458, 9.446, 7.198],
    [1.722, 4.782, 8.106, 0.758, 3.758],
]
"""Box & Tiao's simulated yields, lme4's data set ``Dyestuff2`` (6 batches x 5): lme4's own
example of a boundary fit."""


def test_dyestuff2_matches_lme4s_published_fit() -> None:
    """``lmer(Yield ~ 1 + (1 | Batch), Dyestuff2)`` prints: Batch variance 0.00, residual
    variance 13.81 (SD 3.716), intercept 5.6656 (SE 0.6784), REML criterion 161.8; the
    residual variance is exactly the sample variance of the 30 yields."""
    y = np.array(DYESTUFF2).ravel()
    stats = _Stats.of(np.ones((len(y), 1)), y, np.repeat(np.arange(6), 5))
    theta, notes = _fit_variances(stats)
    assert theta[0] == 0.0 and any("boundary" in n for n in notes)
    assert theta[1] == pytest.approx(np.var(y, ddof=1), rel=1e-12)
    assert round(float(theta[1]), 2) == 13.81 and round(float(np.sqrt(theta[1])), 3) == 3.716
    cov, b, ll = stats.gls(theta)
    assert round(float(b[0]), 4) == 5.6656 and round(float(np.sqrt(cov[0, 0])), 4) == 0.6784
    assert round(-2 * ll, 1) == 161.8
    assert profiled_reml(stats, 1e-6)[0] < ll  # the boundary really is the maximum


def test_interior_fit_profiles_the_residual_variance() -> None:
    """Away from the boundary the residual variance is the profiled one, r'V^-1 r / (n - p),
    at the fitted ratio, and the REML likelihood is maximal there."""
    d = _balanced(seed=3)
    x = np.column_stack([np.ones(len(d)), (d["b"] == "b2").to_numpy(float)])
    groups = np.unique(d["sub"], return_inverse=True)[1]
    stats = _Stats.of(x, d["y"].to_numpy(), groups)
    theta, _ = _fit_variances(stats)
    gamma = theta[0] / theta[1]
    assert gamma > 0.1
    ll, again = profiled_reml(stats, gamma)
    assert again == pytest.approx(theta, rel=1e-12)
    for step in (0.99, 1.01):
        assert profiled_reml(stats, gamma * step)[0] < ll

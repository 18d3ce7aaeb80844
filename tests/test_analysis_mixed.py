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

from analysis.errors import DesignError
from analysis.mixed import mixed_anova, satterthwaite_df

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


def test_cli_mixed_option(tmp_path: Path) -> None:
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
    bad = subprocess.run(
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
            "--mixed",
            "--model",
            "factorial",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2 and "--mixed" in bad.stderr


def test_zero_subject_variance_reduces_to_ordinary_least_squares() -> None:
    """Subject means removed: REML puts s_u^2 on its boundary; the F test is then OLS's on
    N - p df (statsmodels stops short of this optimum; the polish completes it)."""
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
    res = mixed_anova(d, dv="y", subject="sub", factors=["a"])
    row = res.table.iloc[0]
    ols = smf.ols("y ~ C(a, Sum)", data=d).fit()
    assert res.var_subject == 0.0
    assert row["df2"] == pytest.approx(len(d) - 2, rel=1e-4)
    assert row["F"] == pytest.approx(ols.fvalue, rel=1e-6)
    assert any("boundary" in n for n in res.notes)

"""The reviewer's forms beside the paper's: repeated-measures correlation against the ANCOVA it
is defined by, Mauchly's test and GG/HF epsilons against their formulas, the partial eta squared
CI against the noncentral F, Bonferroni CIs against Bonferroni p, and the report/results.json
setting every paper-form test beside its reviewer-form counterpart."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy import stats

from analysis.design import cell_means
from analysis.effect_size import np2_ci, partial_eta_squared
from analysis.errors import DesignError
from analysis.load import from_frames
from analysis.posthoc import Comparison, paired_comparisons
from analysis.results import ASSUMES, FORMS, PAIRS, STAT_COLUMNS
from analysis.rm_anova import effect_contrasts, rm_anova, sphericity
from analysis.rmcorr import rm_corr
from analysis.synthetic import synthetic_tables


def _repeated_pairs(seed: int = 0, n_subjects: int = 7, per: int = 5) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for s in range(n_subjects):
        offset = rng.normal(0, 5)  # between-subject differences rmcorr must ignore
        for _ in range(per):
            x = rng.normal(offset, 1)
            rows.append({"s": f"s{s}", "x": x, "y": -2 * offset + 0.6 * x + rng.normal()})
    return pd.DataFrame(rows)


def test_rm_corr_is_the_subject_ancova() -> None:
    d = _repeated_pairs()
    r = rm_corr(d, x="x", y="y", subject="s")
    fit = smf.ols("y ~ C(s) + x", data=d).fit()
    assert r["df"] == fit.df_resid == 35 - 7 - 1
    assert r["t"] == pytest.approx(fit.tvalues["x"]) and r["p"] == pytest.approx(fit.pvalues["x"])
    ss_x = fit.params["x"] ** 2 * ((d["x"] - d.groupby("s")["x"].transform("mean")) ** 2).sum()
    assert r["r"] ** 2 == pytest.approx(ss_x / (ss_x + fit.ssr))
    z, h = np.arctanh(r["r"]), stats.norm.ppf(0.975) / np.sqrt(r["df"] - 3)
    assert (r["ci_low"], r["ci_high"]) == pytest.approx((np.tanh(z - h), np.tanh(z + h)))
    # shifting each subject's values leaves r_rm unchanged; Pearson r on all pairs is misled
    shifted = d.assign(y=d["y"] + d["s"].str[1:].astype(int) * 10.0)
    assert rm_corr(shifted, x="x", y="y", subject="s")["r"] == pytest.approx(r["r"])
    assert r["r"] > 0 > stats.pearsonr(d["x"], d["y"])[0]


def test_rm_corr_needs_repeated_pairs() -> None:
    d = pd.DataFrame({"s": ["a", "b", "c"], "x": [1.0, 2, 3], "y": [2.0, 1, 3]})
    with pytest.raises(DesignError, match="two or more pairs"):
        rm_corr(d, x="x", y="y", subject="s")


def _three_level(seed: int, n: int = 10) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    cov = np.array([[1.0, 0.8, 0.1], [0.8, 1.0, 0.3], [0.1, 0.3, 2.0]])  # not spherical
    y = rng.multivariate_normal([0, 0.5, 1.0], cov, size=n)
    return pd.DataFrame(
        {
            "sub": np.repeat([f"s{i}" for i in range(n)], 3),
            "c": np.tile(["l1", "l2", "l3"], n),
            "y": y.ravel(),
        }
    )


def test_mauchly_and_huynh_feldt_follow_their_formulas() -> None:
    d = _three_level(4)
    row = rm_anova(d, dv="y", subject="sub", within=["c"]).table.iloc[0]
    cells = cell_means(d, dv="y", subject="sub", within=["c"])
    y = cells.values
    # any orthonormal contrast basis: here a rotation of the Helmert one
    k = effect_contrasts([3], (0,))
    theta = 0.7
    rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    z = y @ k @ rot
    s = np.cov(z, rowvar=False)
    n, p = y.shape[0], 2
    w = np.linalg.det(s) / (np.trace(s) / p) ** p
    chi2 = -(n - 1 - (2 * p * p + p + 2) / (6 * p)) * np.log(w)
    assert row["mauchly_W"] == pytest.approx(w)
    assert row["mauchly_chi2"] == pytest.approx(chi2)
    assert row["mauchly_df"] == 2 and row["mauchly_p"] == pytest.approx(stats.chi2.sf(chi2, 2))
    gg = np.trace(s) ** 2 / (p * np.trace(s @ s))
    hf = min(1.0, (n * p * gg - 2) / (p * (n - 1 - p * gg)))
    assert row["eps_gg"] == pytest.approx(gg) and row["eps_hf"] == pytest.approx(hf)
    assert row["p_hf"] == pytest.approx(stats.f.sf(row["F"], 2 * hf, 2 * (n - 1) * hf))
    assert row["p"] <= row["p_hf"] <= row["p_gg"]


def test_sphericity_of_a_spherical_sample_and_of_one_df() -> None:
    z = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])  # S proportional to I
    out = sphericity(z)
    assert out["mauchly_W"] == pytest.approx(1.0) and out["eps_gg"] == pytest.approx(1.0)
    assert out["mauchly_p"] == pytest.approx(1.0)
    one = sphericity(np.array([[1.0], [-1.0], [0.5]]))
    assert one["eps_gg"] == 1 and np.isnan(one["mauchly_W"])


def test_np2_ci_of_an_effect_without_error_is_not_computable_rather_than_a_crash() -> None:
    """A simulated pilot gave an F of 1.2e31 (an effect every participant showed exactly): the
    report died in scipy's root finder; the CI is now NaN and the rest of the report stands."""
    assert all(math.isnan(v) for v in np2_ci(1.2e31, 1, 7))
    lo, hi = np2_ci(3e6, 1, 7)  # large but finite: still inverted
    assert 0.99998 < lo < hi < 1.0


@pytest.mark.parametrize(("f", "df1", "df2"), [(6.58, 1, 48), (11.73, 2, 10), (1.7, 1, 7)])
def test_np2_ci_inverts_the_noncentral_f(f: float, df1: int, df2: int) -> None:
    lo, hi = np2_ci(f, df1, df2)
    assert lo <= partial_eta_squared(f, df1, df2) <= hi

    def lam(e: float) -> float:
        return e / (1 - e) * (df1 + df2 + 1)

    assert stats.ncf.cdf(f, df1, df2, lam(hi)) == pytest.approx(0.025, abs=1e-6)
    p = stats.f.sf(f, df1, df2)
    if p < 0.025:
        assert stats.ncf.cdf(f, df1, df2, lam(lo)) == pytest.approx(0.975, abs=1e-6)
    else:
        assert lo == 0


def test_bonferroni_ci_excludes_zero_exactly_when_bonferroni_p_is_significant() -> None:
    rng = np.random.default_rng(3)
    comps = [
        Comparison("fam", f"c{i}", rng.normal(shift, 1, 9), rng.normal(0, 1, 9))
        for i, shift in enumerate([0.0, 0.6, 0.9, 1.5, 2.5])
    ]
    out = paired_comparisons(comps)
    assert (out["ci_low_bonf"] <= out["ci_low"]).all()
    excludes = (out["ci_low_bonf"] > 0) | (out["ci_high_bonf"] < 0)
    assert (excludes == (out["p_bonf"] < 0.05)).all()


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, str]:
    from analysis.report import write_report

    t = synthetic_tables(8, seed=4, rate_hz=10.0)
    out = tmp_path_factory.mktemp("reviewer")
    files = write_report(from_frames(t["trials"], t["samples"]), out)
    return json.loads(files.results_json.read_text()), files.markdown.read_text()


def test_results_json_sets_each_paper_test_beside_the_reviewers(report: tuple[dict, str]) -> None:
    doc, _ = report
    stats_ = pd.DataFrame(doc["statistics"])
    assert list(stats_.columns) == STAT_COLUMNS
    for analysis in (
        "timing_mixed",
        "timing_posthoc_subject",
        "preference_rmcorr",
        "prediction_rm",
    ):
        rows = stats_[stats_.analysis == analysis]
        assert len(rows) and (rows["form"] == "reviewer").all()
        assert rows["assumes"].str.len().gt(20).all()
    assert (
        stats_[
            stats_.analysis.isin(
                ["timing_ancova", "timing_posthoc", "preference", "prediction_anova"]
            )
        ]["form"]
        == "as in the paper"
    ).all()
    mixed = stats_[stats_.analysis == "timing_mixed"].set_index("effect")
    assert mixed["method"].str.contains("Satterthwaite").all()
    # participant-level covariates: about n - 1 - 2 df, not the paper's 53
    assert mixed.loc["training_time_s", "df2"] == pytest.approx(5, abs=0.5)
    assert mixed.loc["difficulty", "df2"] == pytest.approx(48, abs=0.5)
    post = stats_[stats_.analysis == "timing_posthoc_subject"]
    assert set(post["df1"]) == {7} and post["ci_low_bonf"].notna().all()
    assert set(stats_[stats_.analysis == "preference_rmcorr"]["df1"]) == {32 - 8 - 1}
    assert set(stats_[stats_.analysis == "prediction_rm"]["df2"]) == {7}
    pairs = pd.DataFrame(doc["paper_vs_reviewer"])
    assert set(pairs["analysis"]) == set(PAIRS)
    assert "timing_mixed" in doc["fits"] and doc["fits"]["timing_mixed"]["df_method"]
    anova_rows = stats_[stats_.test.str.contains("ANOVA|mixed model")]
    assert anova_rows["ci_low"].notna().all() and anova_rows["ci_level"].str.len().gt(0).all()
    assert set(FORMS) == set(ASSUMES)  # every analysis has a form and an assumption line


def test_report_labels_forms_and_assumptions(report: tuple[dict, str]) -> None:
    _, md = report
    assert "The paper's tests beside the reviewer's forms" in md
    assert md.count("Assumes:") >= 6
    assert "(as in the paper)" in md and "(reviewer's form)" in md
    assert "95% CI (unadjusted)" in md and "Bonferroni CI" in md
    assert "Satterthwaite" in md

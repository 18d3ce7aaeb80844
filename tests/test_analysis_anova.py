"""ANOVA engines against independent references: textbook sums of squares written out by hand,
statsmodels' AnovaRM and OLS/anova_lm, plus the command line on good and bad input."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats
from statsmodels.stats.anova import AnovaRM, anova_lm

from analysis.__main__ import main as analysis_main
from analysis.anova import covariate_anova, factorial_anova
from analysis.errors import DesignError, SchemaError
from analysis.rm_anova import rm_anova
from tests.support.cli import Ran, run_main

ROOT = Path(__file__).resolve().parents[1]


def _design(n: int, levels: dict[str, list[str]], seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for s in range(n):
        base = rng.normal(0, 2)
        for combo in itertools.product(*levels.values()):
            cell = dict(zip(levels, combo, strict=True))
            effect = sum(
                0.7 * i * (j + 1)
                for j, v in enumerate(combo)
                for i, lv in enumerate(levels[list(levels)[j]])
                if v == lv
            )
            rows.append({"sub": f"p{s}", **cell, "y": base + effect + rng.normal()})
    return pd.DataFrame(rows)


def test_one_way_matches_textbook_sums_of_squares() -> None:
    # 5 subjects x 3 conditions, integers; classical partition SS_total = SS_subj + SS_A + SS_err.
    y = np.array([[3, 5, 7], [2, 4, 9], [4, 4, 8], [1, 3, 6], [5, 6, 10]], dtype=float)
    n, k = y.shape
    g = y.mean()
    ss_a = n * ((y.mean(axis=0) - g) ** 2).sum()
    ss_subj = k * ((y.mean(axis=1) - g) ** 2).sum()
    ss_err = ((y - g) ** 2).sum() - ss_a - ss_subj
    f_ref = (ss_a / (k - 1)) / (ss_err / ((k - 1) * (n - 1)))
    # Greenhouse-Geisser epsilon by Box's formula on the covariance matrix of the conditions.
    s = np.cov(y, rowvar=False)
    num = k**2 * (np.diag(s).mean() - s.mean()) ** 2
    den = (k - 1) * ((s**2).sum() - 2 * k * (s.mean(axis=1) ** 2).sum() + k**2 * s.mean() ** 2)
    eps_ref = num / den
    long = pd.DataFrame(
        [{"sub": f"s{i}", "cond": f"c{j}", "y": y[i, j]} for i in range(n) for j in range(k)]
    )
    row = rm_anova(long, dv="y", subject="sub", within=["cond"]).table.iloc[0]
    assert (row.df1, row.df2) == (2, 8)
    # By hand: totals 15, 22, 40 (N = 15, sum y^2 = 487): SS_A = 461.8 - 395.267 = 66.533,
    # SS_subjects = 20.4, SS_error = 4.8, F = (66.533 / 2) / (4.8 / 8) = 499 / 9.
    assert f_ref == pytest.approx(499 / 9)
    assert float(row["F"]) == pytest.approx(499 / 9, rel=1e-12)
    assert row.np2 == pytest.approx(ss_a / (ss_a + ss_err))
    assert row.eps_gg == pytest.approx(min(1.0, eps_ref), rel=1e-10)
    assert row.p == pytest.approx(stats.f.sf(f_ref, 2, 8))


def test_two_way_matches_hand_written_partition() -> None:
    d = _design(6, {"A": ["a1", "a2", "a3"], "B": ["b1", "b2"]}, seed=3)
    cube = d.pivot_table(index="sub", columns=["A", "B"], values="y").to_numpy().reshape(6, 3, 2)
    n, a, b = cube.shape
    g = cube.mean()
    ma, mb, ms = cube.mean(axis=(0, 2)), cube.mean(axis=(0, 1)), cube.mean(axis=(1, 2))
    mab = cube.mean(axis=0)
    mas, mbs = cube.mean(axis=2), cube.mean(axis=1)  # (n, a), (n, b)
    ss_a = n * b * ((ma - g) ** 2).sum()
    ss_b = n * a * ((mb - g) ** 2).sum()
    ss_ab = n * ((mab - ma[:, None] - mb[None, :] + g) ** 2).sum()
    ss_as = b * ((mas - ms[:, None] - ma[None, :] + g) ** 2).sum()
    ss_bs = a * ((mbs - ms[:, None] - mb[None, :] + g) ** 2).sum()
    resid = (
        cube
        - mab[None]
        - mas[:, :, None]
        - mbs[:, None, :]
        + ma[None, :, None]
        + mb[None, None, :]
        + ms[:, None, None]
        - g
    )
    ss_abs = (resid**2).sum()
    ref = {
        "A": (ss_a / 2) / (ss_as / 10),
        "B": (ss_b / 1) / (ss_bs / 5),
        "A:B": (ss_ab / 2) / (ss_abs / 10),
    }
    table = rm_anova(d, dv="y", subject="sub", within=["A", "B"]).table.set_index("effect")
    for effect, f in ref.items():
        assert table.loc[effect, "F"] == pytest.approx(f, rel=1e-10)
    assert table.loc["A:B", "np2"] == pytest.approx(ss_ab / (ss_ab + ss_abs))
    assert list(table["df2"]) == [10, 5, 10]


def test_three_factors_match_statsmodels_anovarm_with_awkward_names() -> None:
    # Factors named like patsy keywords and with spaces: our engine has no formula parser.
    levels = {"C": ["lo", "mid", "hi"], "I": ["x", "y"], "task type": ["e", "f"]}
    d = _design(8, levels, seed=5)
    ours = rm_anova(d, dv="y", subject="sub", within=list(levels)).table.set_index("effect")
    safe = d.rename(columns={"C": "fc", "I": "fi", "task type": "ft"})
    ref = AnovaRM(safe, "y", "sub", within=["fc", "fi", "ft"]).fit().anova_table
    rename = {"fc": "C", "fi": "I", "ft": "task type"}
    for name, row in ref.iterrows():
        effect = ":".join(rename[p] for p in name.split(":"))
        assert ours.loc[effect, "F"] == pytest.approx(row["F Value"], rel=1e-9)
        assert ours.loc[effect, "df1"] == row["Num DF"]
        assert ours.loc[effect, "df2"] == row["Den DF"]
        assert ours.loc[effect, "p"] == pytest.approx(row["Pr > F"], rel=1e-7)


def test_published_r_ezanova_values_on_statsmodels_reference_data() -> None:
    # statsmodels ships this 8-subject, 2 x 3 x 2 data set with its tests; the F values below
    # are R's ez::ezANOVA output for it (as printed in statsmodels' test_anova_rm.py).
    import statsmodels

    path = (
        Path(statsmodels.__file__).parent / "stats" / "tests" / "results" / "anova-rm-test-data.csv"
    )
    data = pd.read_csv(path)
    ours = rm_anova(data, dv="DV", subject="id", within=["A", "B", "D"]).table
    ez = [  # df1, df2, F, p  for A, B, D, A:B, A:D, B:D, A:B:D
        (1, 7, 8.7650709, 0.021087505),
        (2, 14, 8.4985785, 0.003833921),
        (1, 7, 20.5076546, 0.002704428),
        (2, 14, 0.8457797, 0.450021759),
        (1, 7, 21.7593382, 0.002301792),
        (2, 14, 6.2416695, 0.011536846),
        (2, 14, 5.4253359, 0.018010647),
    ]
    assert list(ours["effect"]) == ["A", "B", "D", "A:B", "A:D", "B:D", "A:B:D"]
    np.testing.assert_allclose(ours[["df1", "df2", "F", "p"]].to_numpy(), np.array(ez), rtol=1e-6)
    one = rm_anova(data.iloc[:16], dv="DV", subject="id", within=["B"]).table.iloc[0]
    assert (one["df1"], one["df2"]) == (1, 7)
    assert float(one["F"]) == pytest.approx(22.4, rel=1e-6)


def _paper_shaped(seed: int = 1) -> pd.DataFrame:
    """8 participants x 2x2x2 cells with three covariates, like the paper's timing data."""
    rng = np.random.default_rng(seed)
    rows = []
    for s in range(8):
        skill, base_rating = rng.normal(40, 8), rng.integers(2, 7)
        order = rng.permutation(8)
        for i, (dif, cor, mode) in enumerate(
            itertools.product(["easy", "hard"], ["right", "wrong"], ["timid", "aggressive"])
        ):
            t = (
                15
                + 0.2 * skill
                + 20 * (dif == "hard")
                + 30 * (cor == "wrong") * (mode == "aggressive")
                - 8 * (cor == "right") * (mode == "aggressive")
                + rng.normal(0, 6)
            )
            rows.append(
                {
                    "participant": f"P{s}",
                    "difficulty": dif,
                    "correctness": cor,
                    "mode": mode,
                    "duration_s": t,
                    "training_time_s": skill,
                    "baseline_rating": float(base_rating),
                    "tasks_completed": int(order[i]),
                }
            )
    return pd.DataFrame(rows)


@pytest.mark.parametrize("ss_type", [2, 3])
def test_factorial_with_covariates_matches_statsmodels_ols(ss_type: int) -> None:
    d = _paper_shaped()
    cov = ["training_time_s", "baseline_rating", "tasks_completed"]
    res = factorial_anova(
        d,
        dv="duration_s",
        factors=["difficulty", "correctness", "mode"],
        covariates=cov,
        ss_type=ss_type,
    )
    assert res.df_resid == 53  # 64 - 8 cells - 3 covariates, the paper's F(1, 53)
    model = smf.ols(
        "duration_s ~ C(difficulty, Sum) * C(correctness, Sum) * C(mode, Sum) + "
        "training_time_s + baseline_rating + tasks_completed",
        data=d,
    ).fit()
    ref = anova_lm(model, typ=ss_type)
    assert res.r2 == pytest.approx(model.rsquared, rel=1e-10)
    table = res.table.set_index("effect")
    for name, row in ref.drop(index=["Residual", "Intercept"], errors="ignore").iterrows():
        effect = ":".join(p.split("(")[1].split(",")[0] if "(" in p else p for p in name.split(":"))
        assert table.loc[effect, "F"] == pytest.approx(row["F"], rel=1e-8)
        assert table.loc[effect, "df2"] == 53


@pytest.mark.parametrize("ss_type", [2, 3])
def test_unbalanced_three_level_factorial_matches_statsmodels(ss_type: int) -> None:
    rng = np.random.default_rng(9)
    rows = []
    for a, b in itertools.product(["a1", "a2", "a3"], ["b1", "b2"]):
        for _ in range(int(rng.integers(3, 9))):  # unequal cell sizes
            x = rng.normal()
            rows.append(
                {
                    "A": a,
                    "B": b,
                    "x": x,
                    "y": (a == "a2") * 1.5 + (b == "b2") * (a == "a3") + 0.5 * x + rng.normal(),
                }
            )
    d = pd.DataFrame(rows)
    res = factorial_anova(d, dv="y", factors=["A", "B"], covariates=["x"], ss_type=ss_type)
    ref = anova_lm(smf.ols("y ~ C(A, Sum) * C(B, Sum) + x", data=d).fit(), typ=ss_type)
    ours = res.table.set_index("effect")["F"]
    assert ours["A"] == pytest.approx(ref.loc["C(A, Sum)", "F"], rel=1e-8)
    assert ours["B"] == pytest.approx(ref.loc["C(B, Sum)", "F"], rel=1e-8)
    assert ours["A:B"] == pytest.approx(ref.loc["C(A, Sum):C(B, Sum)", "F"], rel=1e-8)
    assert ours["x"] == pytest.approx(ref.loc["x", "F"], rel=1e-8)
    assert res.df_resid == len(d) - 6 - 1


def test_covariate_anova_aggregates_repeats_and_keeps_df() -> None:
    d = _paper_shaped()
    doubled = pd.concat([d, d.assign(duration_s=d.duration_s + 2.0)], ignore_index=True)
    res = covariate_anova(
        doubled,
        dv="duration_s",
        subject="participant",
        within=["difficulty", "correctness", "mode"],
        covariates=["training_time_s", "baseline_rating", "tasks_completed"],
    )
    assert res.df_resid == 53
    assert any("averaged" in n for n in res.notes)


def test_missing_cells_name_participants_and_cells() -> None:
    d = _paper_shaped()
    d = d.drop(
        index=d.index[
            (d.participant == "P3")
            & (d["mode"] == "timid")
            & (d.correctness == "wrong")
            & (d.difficulty == "hard")
        ]
    )
    with pytest.raises(DesignError) as err:
        rm_anova(
            d, dv="duration_s", subject="participant", within=["difficulty", "correctness", "mode"]
        )
    msg = str(err.value)
    assert "P3 lacks difficulty=hard & correctness=wrong & mode=timid" in msg
    assert "drop" in msg
    assert err.value.missing == {"P3": ["difficulty=hard & correctness=wrong & mode=timid"]}
    res = rm_anova(
        d,
        dv="duration_s",
        subject="participant",
        within=["difficulty", "correctness", "mode"],
        drop_incomplete=True,
    )
    assert res.n_subjects == 7 and set(res.table.df2) == {6}


def test_bad_input_messages() -> None:
    d = _paper_shaped()
    with pytest.raises(SchemaError, match="must be numeric"):
        rm_anova(d, dv="mode", subject="participant", within=["difficulty"])
    with pytest.raises(SchemaError, match="no column"):
        rm_anova(d, dv="time", subject="participant", within=["difficulty"])
    with pytest.raises(DesignError, match="at least two levels"):
        rm_anova(d[d["mode"] == "timid"], dv="duration_s", subject="participant", within=["mode"])
    with pytest.raises(DesignError, match="constant"):
        factorial_anova(d.assign(k=1.0), dv="duration_s", factors=["mode"], covariates=["k"])


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(min_value=3, max_value=12), seed=st.integers(0, 10_000), shift=st.floats(-50, 50)
)
def test_two_level_effect_is_the_squared_paired_t(n: int, seed: int, shift: float) -> None:
    # For one two-level within factor, F(1, n-1) equals the paired t statistic squared, and a
    # per-subject constant (a subject effect) changes nothing.
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=n), rng.normal(size=n) + 0.3
    subj = rng.normal(0, 5, size=n)
    long = pd.DataFrame(
        {
            "s": np.tile(np.arange(n), 2),
            "f": ["a"] * n + ["b"] * n,
            "y": np.r_[a + subj, b + subj] + shift,
        }
    )
    row = rm_anova(long, dv="y", subject="s", within=["f"]).table.iloc[0]
    ref = stats.ttest_rel(a, b)
    assert float(row["F"]) == pytest.approx(ref.statistic**2, rel=1e-9)
    assert float(row["p"]) == pytest.approx(ref.pvalue, rel=1e-7)
    shuffled = long.sample(frac=1.0, random_state=seed)
    assert float(
        rm_anova(shuffled, dv="y", subject="s", within=["f"]).table.iloc[0]["F"]
    ) == pytest.approx(float(row["F"]))


def test_between_subject_factor_is_named() -> None:
    d = _paper_shaped()
    d["group"] = np.where(d["participant"].isin(["P0", "P1", "P2", "P3"]), "g1", "g2")
    with pytest.raises(DesignError, match="'group' does not vary within subjects"):
        rm_anova(d, dv="duration_s", subject="participant", within=["mode", "group"])


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "analysis", "anova", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def _cli_here(capsys: pytest.CaptureFixture[str], *args: str) -> Ran:
    """``python -m analysis anova``'s ``main`` in this process (exit code and what it printed,
    without an interpreter's start-up and imports, about 1.4 CPU s a command)."""
    return run_main(analysis_main, ["anova", *args], capsys)


def test_cli_prints_effect_rows_and_reports_problems(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The first command runs as a user runs it (a new process: the table on stdout, the note
    on stderr); the others call the same ``main`` here."""
    d = _paper_shaped().rename(columns={"mode": "C"})
    d = pd.concat([d, d.iloc[:3]], ignore_index=True)  # repeated rows -> averaged, with a note
    path = tmp_path / "long.csv"
    d.to_csv(path, index=False)
    ok = _cli(
        "--csv",
        str(path),
        "--dv",
        "duration_s",
        "--subject",
        "participant",
        "--within",
        "difficulty",
        "correctness",
        "C",
    )
    assert ok.returncode == 0, ok.stderr
    out = pd.read_csv(__import__("io").StringIO(ok.stdout))
    assert list(out.columns[:6]) == ["effect", "df1", "df2", "F", "p", "np2"]
    assert len(out) == 7 and set(out.df2) == {7}
    assert "averaged" in ok.stderr
    js = _cli_here(
        capsys,
        "--csv",
        str(path),
        "--dv",
        "duration_s",
        "--subject",
        "participant",
        "--within",
        "difficulty",
        "correctness",
        "C",
        "--covariates",
        "training_time_s",
        "baseline_rating",
        "tasks_completed",
        "--format",
        "json",
    )
    rows = json.loads(js.stdout)
    assert {r["df2"] for r in rows} == {53.0} and rows[0]["effect"] == "difficulty"
    bad = _cli_here(
        capsys,
        "--csv",
        str(path),
        "--dv",
        "C",
        "--subject",
        "participant",
        "--within",
        "difficulty",
    )
    assert bad.returncode == 2 and "must be numeric" in bad.stderr
    assert "Traceback" not in bad.stderr
    d.iloc[4:].to_csv(path, index=False)  # P0 now lacks cells
    miss = _cli_here(
        capsys,
        "--csv",
        str(path),
        "--dv",
        "duration_s",
        "--subject",
        "participant",
        "--within",
        "difficulty",
        "correctness",
        "C",
    )
    assert miss.returncode == 2 and "P0 lacks" in miss.stderr and "Traceback" not in miss.stderr
    gone = _cli_here(
        capsys,
        "--csv",
        str(tmp_path / "absent.csv"),
        "--dv",
        "y",
        "--subject",
        "s",
        "--within",
        "a",
    )
    assert gone.returncode == 2 and "not found" in gone.stderr

"""Power by resampling participants: against the closed-form power of a paired t test (noncentral
t) on synthetic normal data, the vectorised tests against the package's scalar ones, Wilson's
interval against statsmodels, and the command line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from statsmodels.stats.proportion import proportion_confint

from analysis.__main__ import main as analysis_main
from analysis.anova import covariate_anova
from analysis.errors import DesignError
from analysis.load import from_frames, task_cells
from analysis.posthoc import paired_t
from analysis.power import (
    BOTH,
    CELLS,
    EFFECTS,
    PilotCells,
    ancova_batch,
    bootstrap_power,
    default_tests,
    paired_t_batch,
    pilot_cells,
    wilson,
)
from analysis.rm_anova import rm_anova
from analysis.synthetic import synthetic_tables
from tests.support.cli import run_main

ROOT = Path(__file__).resolve().parents[1]
HARD_RIGHT = (CELLS.index(("hard", "right", "aggressive")), CELLS.index(("hard", "right", "timid")))


@pytest.fixture(scope="module")
def study_cells() -> pd.DataFrame:
    t = synthetic_tables(8, seed=21, rate_hz=5.0)
    return task_cells(from_frames(t["trials"]).trials)[0]


def _normal_pilot(effect: float, n: int = 4000, seed: int = 0) -> PilotCells:
    """A large 'population' whose Hard&Right aggressive - timid differences are N(effect, 1)."""
    rng = np.random.default_rng(seed)
    y = rng.normal(20, 3, size=(n, 8))
    y[:, HARD_RIGHT[0]] = y[:, HARD_RIGHT[1]] + rng.normal(effect, 1.0, n)
    return PilotCells(
        participants=tuple(f"p{i}" for i in range(n)),
        durations=y,
        practice=None,
        covariates=np.zeros((n, 0)),
        covariate_names=(),
    )


@pytest.mark.parametrize("effect", [-0.45, -0.8])
def test_power_matches_the_noncentral_t_closed_form(effect: float) -> None:
    """Hard&Right test: two-sided alpha/2 (Bonferroni over 2), counted in the hypothesised
    (negative) direction, so power = P(T' < -t_crit) with T' ~ t(N - 1, d sqrt(N)). With
    B = 2000 the Monte-Carlo SE is at most 0.0112; we allow 4 SE."""
    pilot = _normal_pilot(effect)
    test = [t for t in default_tests() if t.name.startswith("Hard&Right")]
    b, ns = 2000, (6, 10, 16, 24)
    res = bootstrap_power(pilot, ns=ns, b=b, seed=5, tests=test)
    d = pilot.durations[:, HARD_RIGHT[0]] - pilot.durations[:, HARD_RIGHT[1]]
    dz = d.mean() / d.std(ddof=0)  # the resampled population's standardised effect
    for row in res.table.itertuples():
        n = row.n
        crit = stats.t.ppf(1 - 0.05 / 4, n - 1)
        exact = stats.nct.cdf(-crit, n - 1, dz * np.sqrt(n))
        se = np.sqrt(exact * (1 - exact) / b)
        assert abs(row.power - exact) <= 4 * max(se, 1 / b), (n, row.power, exact)
        assert row.ci_low <= row.power <= row.ci_high


def test_vectorised_tests_equal_the_scalar_implementations(study_cells: pd.DataFrame) -> None:
    pilot = pilot_cells(study_cells)
    y, pr, cov = pilot.durations[None], pilot.practice[None], pilot.covariates[None]
    batch = ancova_batch(y, pr, cov, list(EFFECTS))
    ref = covariate_anova(
        study_cells,
        dv="duration_s",
        subject="participant",
        within=["difficulty", "correctness", "mode"],
        covariates=["training_time_s", "baseline_rating", "tasks_completed"],
    ).table.set_index("effect")
    rm = rm_anova(
        study_cells,
        dv="duration_s",
        subject="participant",
        within=["difficulty", "correctness", "mode"],
    ).table.set_index("effect")
    for e in EFFECTS:
        assert batch[e][0][0] == pytest.approx(ref.loc[e, "F"], rel=1e-8)
        assert batch[e][1][0] == pytest.approx(ref.loc[e, "p"], rel=1e-6)
        t, p = paired_t_batch(pilot.durations @ EFFECTS[e] / 4)
        assert t**2 == pytest.approx(rm.loc[e, "F"], rel=1e-8) and p == pytest.approx(
            rm.loc[e, "p"], rel=1e-6
        )
    a, b = pilot.durations[:, HARD_RIGHT[0]], pilot.durations[:, HARD_RIGHT[1]]
    assert paired_t_batch(a - b)[1] == pytest.approx(paired_t(a, b)["p"])


def test_default_run_reports_both_forms_and_n_for_80_percent(study_cells: pd.DataFrame) -> None:
    res = bootstrap_power(pilot_cells(study_cells), ns=(8, 16), b=200, seed=1)
    t = res.table
    assert set(t["n"]) == {8, 16} and (t["b"] == 200).all()
    assert set(t[t.hypothesis == "H1"]["form"]) == {"as in the paper", "reviewer"}
    assert "both planned comparisons" in set(t["test"]) and BOTH in set(t["form"])
    assert ((t["ci_low"] <= t["power"]) & (t["power"] <= t["ci_high"])).all()
    joint = t[t.test == "both planned comparisons"].set_index("n")["power"]
    single = t[t.test.str.startswith(("Hard&Right", "Easy&Wrong"))].groupby("n")["power"].min()
    assert (joint <= single + 1e-12).all()  # both significant is rarer than either
    s = res.summary
    assert len(s) == t.groupby(["hypothesis", "test", "form"]).ngroups
    reached = s["n80"].notna()
    assert s[reached]["n80"].isin([8, 16]).all()
    again = bootstrap_power(pilot_cells(study_cells), ns=(8, 16), b=200, seed=1)
    pd.testing.assert_frame_equal(again.table, t)  # seeded


def test_wilson_matches_statsmodels() -> None:
    for k, n in [(0, 50), (7, 50), (50, 50), (812, 1000)]:
        lo, hi = wilson(k, n)
        ref = proportion_confint(k, n, alpha=0.05, method="wilson")
        assert (float(lo), float(hi)) == pytest.approx(ref, abs=1e-12)


def test_errors_say_what_to_do(study_cells: pd.DataFrame) -> None:
    pilot = pilot_cells(study_cells)
    with pytest.raises(DesignError, match="at least 100"):
        bootstrap_power(pilot, b=5)
    with pytest.raises(DesignError, match="at least 3"):
        bootstrap_power(pilot, ns=(2, 8))
    with pytest.raises(DesignError, match="2 x 2 x 2"):
        pilot_cells(study_cells[study_cells.difficulty == "easy"])


def test_cli_writes_table_json_and_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    t = synthetic_tables(6, seed=3, rate_hz=5.0)
    export = tmp_path / "export"
    export.mkdir()
    t["trials"].to_csv(export / "trials.csv", index=False)
    out = tmp_path / "power"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "analysis",
            "power",
            "--export-dir",
            str(export),
            "--out",
            str(out),
            "--n",
            "6",
            "10",
            "--b",
            "200",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((out / "power.json").read_text())
    assert doc["b"] == 200 and doc["ns"] == [6, 10] and doc["participants_in_pilot"] == 6
    assert {r["n"] for r in doc["power"]} == {6, 10}
    assert (out / "power_curve.png").stat().st_size > 10_000 and (out / "power.csv").exists()
    assert "n80" in proc.stdout
    # the same command line's main here: a refused --b is exit 2 with a message
    bad = run_main(
        analysis_main,
        ["power", "--export-dir", str(export), "--out", str(out), "--b", "3"],
        capsys,
    )
    assert bad.returncode == 2 and "at least 100" in bad.stderr


def test_power_zero_and_one_are_drawn(tmp_path: Path) -> None:
    """A huge effect in the hypothesised direction (power 1) and against it (power 0): the
    Wilson ends are exactly 0 and 1, and the figure draws (it raised "'yerr' must not contain
    negative values" on the 2.2e-19 the formula leaves at k = 0)."""
    from analysis.figures import power_figure, save

    for effect, power in ((-40.0, 1.0), (40.0, 0.0)):  # aggressive faster is the hypothesis
        res = bootstrap_power(_normal_pilot(effect, n=200), ns=(4, 8), b=100, seed=2)
        row = res.table[res.table.test.str.startswith("Hard&Right")].set_index("n").loc[8]
        assert row["power"] == power
        ref = proportion_confint(int(power * 100), 100, alpha=0.05, method="wilson")
        assert (row["ci_low"], row["ci_high"]) == pytest.approx(ref, abs=1e-12)
        assert (row["ci_low"] if power == 0 else row["ci_high"]) == power  # exactly
        t = res.table
        assert ((t["ci_low"] <= t["power"]) & (t["power"] <= t["ci_high"])).all()
        saved = save(power_figure(res.table), tmp_path, f"power_{effect:+.0f}", "power")
        assert saved.png.stat().st_size > 10_000
    lo, hi = wilson(np.array([0, 100]), 100)
    assert lo[0] == 0.0 and hi[1] == 1.0

"""Analysis by factor name: the split-plot ANOVA against a hand-computed textbook example, the
mixed model's between term, post-hoc with Bonferroni and Holm, ratings of every declared item,
and the general report of a design other than the paper's."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.errors import DesignError
from analysis.factor_analysis import factor_analysis
from analysis.factor_design import condition_cells, factor_design, is_paper_factors
from analysis.load import from_frames
from analysis.mixed import mixed_anova
from analysis.multiplicity import bonferroni, holm
from analysis.pairwise import pairwise_comparisons
from analysis.protocol_info import DEFAULT_PROTOCOL, load_protocol_info
from analysis.report import write_report
from analysis.rm_anova import rm_anova
from analysis.split_plot import split_plot_anova

# Two groups of four subjects measured on three occasions (a textbook split-plot layout)
GROUP = ["g1"] * 4 + ["g2"] * 4
SCORES = [[0, 4, 4], [0, 7, 9], [3, 4, 6], [5, 9, 9], [1, 3, 3], [3, 1, 3], [6, 6, 6], [6, 6, 8]]


def _textbook() -> pd.DataFrame:
    return pd.DataFrame(
        [
            {"s": f"s{i}", "group": GROUP[i], "time": f"t{j + 1}", "y": float(SCORES[i][j])}
            for i in range(8)
            for j in range(3)
        ]
    )


def test_split_plot_reproduces_the_hand_computed_textbook_sums_of_squares() -> None:
    # by hand: grand mean 4.667; group means 5 and 4.333; occasion means 3, 5, 6
    # SS_group = 12 * 2 * 0.333^2 = 2.667, SS_subjects/group = 3 * 29.333 = 88,
    # SS_time = 8 * 4.667 = 37.333, SS_group x time = 4 * 15.333 - 2.667 - 37.333 = 21.333,
    # SS_total = 692 - 112^2 / 24 = 169.333, so SS_time x subjects/group = 20
    t = split_plot_anova(
        _textbook(), dv="y", subject="s", within=["time"], between=["group"]
    ).table.set_index("effect")
    assert list(t.index) == ["group", "time", "group:time"]
    assert t.loc["group", "SS"] == pytest.approx(8 / 3)
    assert t.loc["group", "SS_error"] == pytest.approx(88.0)
    assert (t.loc["group", "df1"], t.loc["group", "df2"]) == (1.0, 6.0)
    assert t.loc["group", "F"] == pytest.approx((8 / 3) / (88 / 6))  # 0.1818
    assert t.loc["time", "SS"] == pytest.approx(112 / 3)
    assert t.loc["group:time", "SS"] == pytest.approx(64 / 3)
    assert t.loc["time", "SS_error"] == pytest.approx(20.0)
    assert (t.loc["time", "df1"], t.loc["time", "df2"]) == (2.0, 12.0)
    assert t.loc["time", "F"] == pytest.approx(11.2)
    assert t.loc["group:time", "F"] == pytest.approx(6.4)
    assert t.loc["time", "p"] == pytest.approx(stats.f.sf(11.2, 2, 12))
    assert t.loc["time", "error"] == "time x subjects within group"


def test_between_effect_is_the_one_way_anova_of_subject_means_and_interaction_of_differences() -> (
    None
):
    rng = np.random.default_rng(3)
    rows = []
    for i in range(15):  # three groups of unequal-free size 5, two occasions
        g = ("a", "b", "c")[i % 3]
        base = rng.normal(10 + (i % 3), 2)
        for j, occ in enumerate(("pre", "post")):
            rows.append({"s": i, "g": g, "occ": occ, "y": base + j * (1 + i % 3) + rng.normal()})
    d = pd.DataFrame(rows)
    t = split_plot_anova(d, dv="y", subject="s", within=["occ"], between=["g"]).table
    t = t.set_index("effect")
    wide = d.pivot_table(index=["s", "g"], columns="occ", values="y").reset_index()
    means = [wide.loc[wide.g == g, ["pre", "post"]].mean(axis=1) for g in "abc"]
    diffs = [wide.loc[wide.g == g, "post"] - wide.loc[wide.g == g, "pre"] for g in "abc"]
    assert t.loc["g", "F"] == pytest.approx(stats.f_oneway(*means).statistic)
    assert t.loc["g:occ", "F"] == pytest.approx(stats.f_oneway(*diffs).statistic)
    assert t.loc["g:occ", "df2"] == 12.0  # n - groups


def test_without_between_factors_it_is_the_repeated_measures_anova() -> None:
    d = _textbook()
    ours = split_plot_anova(d, dv="y", subject="s", within=["time"]).table
    rm = rm_anova(d, dv="y", subject="s", within=["time"]).table
    cols = ["F", "p", "df1", "df2", "eps_gg", "eps_hf", "mauchly_W", "mauchly_p"]
    pd.testing.assert_frame_equal(ours[cols], rm[cols])


def test_mixed_model_between_term_has_the_split_plot_f_and_df() -> None:
    # balanced, compound symmetric: the random-intercept model's between F and its
    # Satterthwaite df are the split-plot's F(1, n - g); the within F pools the error
    rng = np.random.default_rng(5)
    rows = []
    for i in range(10):
        g = "rel" if i % 2 else "abs"
        u = rng.normal(0, 3)
        for m in ("timid", "aggressive"):
            y = 20 + u + (3 if g == "rel" else 0) + (2 if m == "aggressive" else 0)
            rows.append({"p": f"P{i}", "mapping": g, "mode": m, "y": y + rng.normal(0, 1)})
    d = pd.DataFrame(rows)
    sp = split_plot_anova(d, dv="y", subject="p", within=["mode"], between=["mapping"]).table
    lmm = mixed_anova(d, dv="y", subject="p", factors=["mapping", "mode"]).table
    sp, lmm = sp.set_index("effect"), lmm.set_index("effect")
    assert lmm.loc["mapping", "F"] == pytest.approx(sp.loc["mapping", "F"], rel=1e-6)
    assert lmm.loc["mapping", "df2"] == pytest.approx(8.0, abs=1e-3)
    assert lmm.loc["mode", "F"] == pytest.approx(sp.loc["mode", "F"], rel=1e-6)


def test_a_factor_declared_between_that_varies_within_a_subject_is_refused() -> None:
    d = _textbook().assign(block=lambda f: f["time"])  # varies within each subject
    with pytest.raises(DesignError, match=r"declared between subjects.*declare it within"):
        split_plot_anova(d, dv="y", subject="s", within=["time"], between=["block"])
    with pytest.raises(DesignError, match="is a between-subjects factor"):
        split_plot_anova(d, dv="y", subject="s", within=["group"])


def test_holm_adjusts_step_down_and_never_exceeds_bonferroni() -> None:
    p = [0.01, 0.04, 0.03, 0.005]
    np.testing.assert_allclose(holm(p), [0.03, 0.06, 0.06, 0.02])
    np.testing.assert_allclose(bonferroni(p), [0.04, 0.16, 0.12, 0.02])
    assert (holm(p) <= bonferroni(p)).all()


def _general_trials(n: int = 8, *, seed: int = 0) -> pd.DataFrame:
    """mapping (between) x intent x mode (within), two tasks, items helpful and calm."""
    rng = np.random.default_rng(seed)
    rows, tid = [], 0
    for p in range(n):
        pid, mapping, person = f"P{p + 1:02d}", ("absolute", "relative")[p % 2], rng.normal(0, 3)
        for task in ("near", "far"):
            for intent in ("hidden", "shown"):
                for mode in ("timid", "aggressive"):
                    tid += 1
                    y = 20 + person + 4 * (mapping == "relative") + 3 * (mode == "aggressive")
                    y += -2 * (intent == "shown") + 5 * (task == "far") + rng.normal(0, 2)
                    rows.append(
                        {
                            "participant": pid,
                            "phase": "task",
                            "task": task,
                            "mapping": mapping,
                            "intent": intent,
                            "mode": mode,
                            "status": "completed",
                            "success": True,
                            "duration_s": y,
                            "helpful": int(np.clip(round(6 - y / 8), 1, 7)),
                            "calm": int(rng.integers(1, 8)),
                            "trial_id": tid,
                        }
                    )
        rows.append(
            {
                "participant": pid,
                "phase": "training",
                "task": "practice",
                "mapping": mapping,
                "intent": "",
                "mode": "none",
                "status": "completed",
                "success": True,
                "duration_s": 30.0,
                "trial_id": 1000 + p,
            }
        )
    return pd.DataFrame(rows)


FACTORS = {
    "mapping": ("absolute", "relative"),
    "intent": ("hidden", "shown"),
    "mode": ("timid", "aggressive"),
}


def _design_and_cells() -> tuple[object, pd.DataFrame]:
    trials = from_frames(_general_trials()).trials
    design = factor_design(trials, FACTORS, between=["mapping"])
    cells, _ = condition_cells(trials, design)
    return design, cells


def test_design_reads_within_and_between_factors_by_name() -> None:
    design, cells = _design_and_cells()
    assert design.within == ("intent", "mode") and design.between == ("mapping",)
    assert len(design.conditions) == 4
    assert len(cells) == 8 * 2 * 4  # participant x task x condition
    assert not is_paper_factors(list(FACTORS), ["mapping"])
    assert is_paper_factors(["difficulty", "correctness", "mode"])
    assert not is_paper_factors(["difficulty", "correctness", "mode"], ["mode"])


def test_posthoc_has_every_pair_of_conditions_and_levels_with_holm() -> None:
    design, cells = _design_and_cells()
    fit = split_plot_anova(
        cells,
        dv="duration_s",
        subject="participant",
        within=design.within,
        between=design.between,
        drop_incomplete=True,
    )
    ph = pairwise_comparisons(fit)
    conditions = ph[ph.family == "conditions"]
    assert len(conditions) == 8 * 7 // 2  # 2 groups x 4 conditions = 8 cells
    assert set(conditions.test) == {"paired t", "Welch t"}
    assert set(ph.family) == {"conditions", "mapping levels", "intent levels", "mode levels"}
    assert ph["p_holm"].notna().all()
    assert (ph["p_holm"] <= ph["p_bonf"] + 1e-12).all()
    within = ph[ph.family == "mode levels"].iloc[0]
    wide = cells.groupby(["participant", "mode"], observed=True)["duration_s"].mean().unstack()
    ref = stats.ttest_rel(wide["timid"], wide["aggressive"])
    assert within["t"] == pytest.approx(ref.statistic)
    between = ph[ph.family == "mapping levels"].iloc[0]
    per = cells.groupby(["participant", "mapping"], observed=True)["duration_s"].mean()
    per = per.reset_index()
    ref = stats.ttest_ind(
        per.loc[per.mapping == "absolute", "duration_s"],
        per.loc[per.mapping == "relative", "duration_s"],
        equal_var=False,
    )
    assert between["t"] == pytest.approx(ref.statistic)
    assert between["p"] == pytest.approx(ref.pvalue)


def test_ratings_by_condition_cover_every_declared_item() -> None:
    design, cells = _design_and_cells()
    fa = factor_analysis(cells, design, items=["helpful", "calm"])
    assert set(fa.ratings["item"]) == {"helpful", "calm"}
    assert len(fa.ratings) == 2 * 8  # items x (group x condition)
    assert set(fa.measures) == {"duration_s", "helpful", "calm"}
    one = fa.ratings[(fa.ratings.item == "calm")].iloc[0]
    sel = (
        (cells.mapping == one.mapping)
        & (cells.intent == one.intent)
        & (cells["mode"] == one["mode"])
    )
    assert one["mean"] == pytest.approx(cells.loc[sel, "calm"].mean())


@pytest.fixture(scope="module")
def general_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, dict]:
    proto = dataclasses.replace(
        load_protocol_info(DEFAULT_PROTOCOL),
        factors=FACTORS,
        between=("mapping",),
        rating_items=("helpful", "calm"),
    )
    out = tmp_path_factory.mktemp("general")
    files = write_report(from_frames(_general_trials()), out, protocol=proto)
    return files.markdown.read_text(), json.loads(files.results_json.read_text())


def test_general_report_has_the_general_sections_and_not_the_papers(general_report) -> None:
    md, _ = general_report
    heads = re.findall(r"(?m)^## (.+)$", md)
    for wanted in (
        "Design",
        "Ratings by condition",
        "ANOVA by factor",
        "Post-hoc comparisons by factor",
    ):
        assert wanted in heads, heads
    assert "Timing (section 5.1)" not in heads and "Preferences" not in heads
    assert "Ratings by condition (Fig. 8)" not in heads
    assert "| mapping | between subjects | absolute, relative |" in md
    assert "calm: split-plot ANOVA" in md and "helpful: pairwise comparisons" in md


def test_general_results_json_carries_split_plot_mixed_and_holm_rows(general_report) -> None:
    _, doc = general_report
    st = pd.DataFrame(doc["statistics"])
    anova = st[st.analysis == "factor_anova"].set_index("effect")
    assert anova.loc["duration_s: mapping", "df2"] == 6.0  # n - groups
    assert anova.loc["duration_s: mapping:mode", "df1"] == 1.0
    mixed = st[st.analysis == "factor_mixed"].set_index("effect")
    assert mixed.loc["duration_s: mapping", "df2"] == pytest.approx(6.0, abs=1e-3)
    post = st[st.analysis == "factor_posthoc"]
    assert post["p_holm"].notna().all() and post["p_bonf"].notna().all()
    assert (post["effect"].str.contains("duration_s: conditions: ")).sum() == 28


def _pilot(n: int = 400, *, seed: int = 2, shift: float = 0.5) -> tuple[object, pd.DataFrame]:
    """A large pilot of a 2-level within factor: differences ~ N(shift, 1) per participant."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        base = rng.normal(20, 3)
        d = rng.normal(shift, 1.0)
        for mode, y in (("timid", base), ("aggressive", base + d)):
            rows.append(
                {
                    "participant": f"P{i}",
                    "phase": "task",
                    "task": "t",
                    "mode": mode,
                    "status": "completed",
                    "duration_s": y,
                }
            )
    trials = from_frames(pd.DataFrame(rows)).trials
    design = factor_design(trials, {"mode": ("timid", "aggressive")})
    return design, condition_cells(trials, design)[0]


def test_power_of_a_pair_matches_the_noncentral_t_and_the_effect_matches_the_pair() -> None:
    from analysis.contrast_power import Contrast, contrast_power, pilot_conditions

    design, cells = _pilot()
    pilot = pilot_conditions(cells, design, dv="duration_s")
    pair = Contrast("aggressive - timid", a={"mode": "aggressive"}, b={"mode": "timid"})
    effect = Contrast("main effect of mode", factor="mode")
    res = contrast_power(pilot, [pair, effect], ns=[16], b=2000, seed=1)
    power = res.table.set_index("test")["power"]
    # the pilot's own effect size d_z, as the population's
    diffs = pilot.values[:, 1] - pilot.values[:, 0]
    dz = diffs.mean() / diffs.std(ddof=0)
    crit = stats.t.ppf(0.975, 15)
    nc = dz * np.sqrt(16)
    exact = stats.nct.sf(crit, 15, nc) + stats.nct.cdf(-crit, 15, nc)
    assert power["aggressive - timid"] == pytest.approx(exact, abs=0.035)
    # F(1, N - 1) of a two-level factor is the paired t squared: the same replicates hit
    assert power["main effect of mode"] == power["aggressive - timid"]


def test_power_command_powers_named_contrasts_of_a_between_design(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import analysis.cli.contrast_power as cli
    from analysis.__main__ import main

    proto = dataclasses.replace(
        load_protocol_info(DEFAULT_PROTOCOL), factors=FACTORS, between=("mapping",)
    )
    monkeypatch.setattr(cli, "load_protocol_info", lambda *a, **k: proto)
    pilot = tmp_path / "pilot"
    pilot.mkdir()
    _general_trials(8, seed=1).to_csv(pilot / "trials.csv", index=False)
    out = tmp_path / "power"
    code = main(
        [
            "power",
            "--export-dir",
            str(pilot),
            "--out",
            str(out),
            "--b",
            "200",
            "--n",
            "8",
            "16",
            "--effect",
            "mapping",
            "--effect",
            "intent",
            "--pair",
            "mapping=absolute,mode=timid",
            "mapping=relative,mode=timid",
        ]
    )
    assert code == 0
    doc = json.loads((out / "power.json").read_text())
    tests = {r["test"] for r in doc["n_for_80_percent"]}
    assert tests == {
        "main effect of mapping",
        "main effect of intent",
        "mapping=absolute,mode=timid - mapping=relative,mode=timid",
    }
    assert {r["n"] for r in doc["power"]} == {8, 16}
    bad = main(
        [
            "power",
            "--export-dir",
            str(pilot),
            "--out",
            str(out),
            "--b",
            "200",
            "--pair",
            "mode=fast",
            "mode=timid",
        ]
    )
    assert bad == 2  # a level the design lacks: one line naming the factors and levels

"""The report command end to end on an exported synthetic study, and its failure messages.

The first test runs ``python -m analysis report`` as a user does (a new process); the others
call the same command line's ``main`` in this process (no interpreter start-up and imports,
about 3 CPU s a command), where what is checked is the exit code, the message and the files."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from analysis.__main__ import main as analysis_main
from analysis.load import from_frames, task_cells
from analysis.protocol_info import load_protocol_info
from analysis.synthetic import synthetic_tables
from analysis.timing import timing_analysis
from tests.support.cli import Ran, run_main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def export_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated 8-participant study written like `study export` output (CSV + Parquet)."""
    d = tmp_path_factory.mktemp("export")
    tables = synthetic_tables(8, seed=21, rate_hz=20.0)
    tables["trials"].to_csv(d / "trials.csv", index=False)
    tables["samples"].to_parquet(d / "samples.parquet")
    tables["ratings"].to_csv(d / "ratings.csv", index=False)
    tables["events"].to_csv(d / "events.csv", index=False)
    return d


def _report(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "analysis", "report", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )


def _report_here(capsys: pytest.CaptureFixture[str], *args: str) -> Ran:
    return run_main(analysis_main, ["report", *args], capsys)


def test_report_writes_html_markdown_json_and_figures(export_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    run = _report("--export-dir", str(export_dir), "--out", str(out))
    assert run.returncode == 0, run.stderr
    html = (out / "report.html").read_text()
    assert html.count("<svg") == 4  # Fig. 7, 8 (time and preference; ratings), 9 inline
    assert not re.search(r"<(img|script|link)\b", html)  # self-contained
    for fig in ("fig7_arbitration", "fig8_time_preference", "fig8_ratings", "fig9_prediction"):
        assert (out / "figures" / f"{fig}.png").stat().st_size > 10_000
        assert (out / "figures" / f"{fig}.svg").read_text().lstrip().startswith("<?xml")
    md = (out / "report.md").read_text()
    assert "| effect | df | F | p | partial η² | paper F | paper p |" in md
    assert "| difficulty | 1, 53 |" in md and "18.45" in md
    assert "figures/fig9_prediction.png" in md

    doc = json.loads((out / "results.json").read_text())
    stats = pd.DataFrame(doc["statistics"])
    assert {"analysis", "effect", "test", "df1", "df2", "statistic", "p", "effect_size"} <= set(
        stats.columns
    )

    def row(analysis: str, effect: str) -> pd.Series:
        return stats[(stats.analysis == analysis) & (stats.effect == effect)].iloc[0]

    assert row("timing_ancova", "difficulty")["df2"] == 53
    assert row("timing_ancova", "difficulty")["paper_value"] == 18.45
    assert row("timing_rm", "correctness:mode")["df2"] == 7
    assert (
        row("timing_posthoc", "aggressive&wrong - timid&wrong (aggressive vs timid when wrong)")[
            "df1"
        ]
        == 15
    )
    assert row("timing_planned", "Easy&Wrong: aggressive - timid")["df1"] == 7
    assert row("preference", "time_advantage_aggressive")["df1"] == 30
    assert row("prediction_anova", "predictor")["df2"] == 112
    assert row("prediction_anova", "predictor")["paper_value"] == 1020.95
    # the numbers in the file are the API's numbers on the same data
    cells, _ = task_cells(from_frames(pd.read_csv(export_dir / "trials.csv")).trials)
    api = timing_analysis(cells).ancova.table.set_index("effect")
    assert row("timing_ancova", "mode")["statistic"] == pytest.approx(api.loc["mode", "F"])
    assert doc["fits"]["timing_ancova"]["df_resid"] == 53
    assert doc["protocol"]["content_hash"] == load_protocol_info().content_hash
    assert doc["software"]["version"] and doc["participants"] == 8


def test_report_on_incomplete_data_notes_what_was_dropped(
    export_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "export"
    src.mkdir()
    trials = pd.read_csv(export_dir / "trials.csv")
    trials.loc[(trials.participant == "P05") & (trials.task == "hard-wrong"), "status"] = "skipped"
    trials.to_csv(src / "trials.csv", index=False)  # no samples: prediction is skipped
    run = _report_here(capsys, "--export-dir", str(src), "--out", str(tmp_path / "r"))
    assert run.returncode == 0, run.stderr
    doc = json.loads((tmp_path / "r" / "results.json").read_text())
    assert any("P05" in n for n in doc["notes"])
    assert any("no samples" in n for n in doc["notes"])
    assert doc["fits"]["timing_rm"]["n_subjects"] == 7


def test_report_bad_sources_exit_2_with_a_message(
    tmp_path: Path, export_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    gone = _report_here(
        capsys, "--export-dir", str(tmp_path / "nowhere"), "--out", str(tmp_path / "o")
    )
    assert gone.returncode == 2 and "not a directory" in gone.stderr
    db = _report_here(capsys, "--db", str(tmp_path / "absent.db"), "--out", str(tmp_path / "o"))
    assert db.returncode == 2 and "--db" in db.stderr and "Traceback" not in db.stderr
    broken = tmp_path / "broken"
    broken.mkdir()
    pd.read_csv(export_dir / "trials.csv").drop(columns="duration_s").to_csv(
        broken / "trials.csv", index=False
    )
    bad = _report_here(capsys, "--export-dir", str(broken), "--out", str(tmp_path / "o"))
    assert bad.returncode == 2 and "'duration_s'" in bad.stderr and "Traceback" not in bad.stderr


def test_rendering_escapes_text_and_formats_p_values() -> None:
    from analysis.render import Section, Table, fmt_p, render_html, render_markdown

    meta = {
        "source": "x",
        "generated_at": "now",
        "protocol": {"id": "p"},
        "software": {
            k: "1"
            for k in (
                "package",
                "version",
                "commit",
                "python",
                "numpy",
                "pandas",
                "scipy",
                "statsmodels",
                "matplotlib",
            )
        },
    }
    sec = Section(
        "S",
        paragraphs=["a < b"],
        tables=[
            Table("T", pd.DataFrame({"participant": ["<script>alert(1)</script>"], "v": ["x|y"]}))
        ],
    )
    page = render_html([sec], meta)
    assert "<script>" not in page and "&lt;script&gt;" in page
    assert "x\\|y" in render_markdown([sec], meta)
    assert [fmt_p(p) for p in (0.0004, 0.0021, 0.11, 1.0)] == ["< .001", ".002", ".110", "1.000"]


def test_fig7_curves_follow_the_arbitration_tables() -> None:
    import numpy as np

    from analysis.figures import arbitration_figure

    tables = {
        "timid": {"kind": "timid", "alpha_max": 0.4, "saturation": 0.6},
        "aggressive": {"kind": "aggressive", "threshold": 0.3, "alpha_high": 0.8},
    }
    lines = {ln.get_label(): ln for ln in arbitration_figure(tables).axes[0].lines}
    c = lines["timid"].get_xdata()
    np.testing.assert_allclose(
        lines["timid"].get_ydata(), 0.4 * np.minimum(1.0, c / 0.6), atol=1e-12
    )
    np.testing.assert_allclose(lines["aggressive"].get_ydata(), np.where(c >= 0.3, 0.8, 0.0))


def test_report_with_training_runs_only(tmp_path: Path) -> None:
    from analysis.load import from_frames
    from analysis.report import write_report

    trials = synthetic_tables(2, seed=1, with_samples=False)["trials"]
    files = write_report(from_frames(trials[trials.phase == "training"]), tmp_path)
    doc = json.loads(files.results_json.read_text())
    assert doc["statistics"] == [] and doc["participants"] == 0
    assert any("no completed task trials" in n for n in doc["notes"])
    assert files.html.read_text().count("<svg") == 1  # Fig. 7 from the protocol still drawn


def test_other_designs_three_modes_and_a_single_difficulty(tmp_path: Path) -> None:
    """A protocol like protocols/memory3.toml: one difficulty level, three modes."""
    import numpy as np

    from analysis.load import from_frames
    from analysis.report import write_report

    t = synthetic_tables(8, seed=2, rate_hz=10.0)
    trials, samples = t["trials"], t["samples"]
    trials = trials[(trials.phase == "training") | (trials.difficulty == "easy")]
    timid = trials[trials["mode"] == "timid"]
    offset = int(trials["trial_id"].max())
    rng = np.random.default_rng(0)
    linear = timid.assign(
        mode="linear",
        trial_id=timid["trial_id"] + offset,
        duration_s=timid["duration_s"] + rng.normal(3, 2, len(timid)),
    )
    linear_samples = samples[samples.trial_id.isin(timid["trial_id"])].assign(
        trial_id=lambda d: d["trial_id"] + offset
    )
    tables = from_frames(
        pd.concat([trials, linear], ignore_index=True),
        pd.concat([samples, linear_samples], ignore_index=True),
    )
    files = write_report(tables, tmp_path)
    res = files.results
    assert res.timing is not None and res.timing.factors == ("correctness", "mode")
    assert res.timing.levels["mode"] == ("timid", "aggressive", "linear")
    rm = res.timing.rm.table.set_index("effect")
    assert (rm.loc["mode", "df1"], rm.loc["mode", "df2"]) == (2, 14)
    assert 1 / 2 <= rm.loc["mode", "eps_gg"] <= 1
    comp = res.timing.comparisons
    assert len(comp) == 6 and set(comp["m"]) == {3} and set(comp["df"]) == {7}
    assert res.prediction is not None and res.prediction.df_resid == 96 - 12
    assert any("preference analysis skipped" in n for n in res.notes)
    assert any("differs from the paper" in n for n in res.notes)
    assert files.html.read_text().count("<svg") == 3


MEMORY3 = ROOT / "protocols" / "memory3.toml"


@pytest.fixture(scope="module")
def memory3_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict, str]:
    """Three simulated participants through protocols/memory3.toml, reported without --protocol
    (with two, their two participant-level covariates are collinear unless one is constant)."""
    from analysis.load import load_tables
    from analysis.report import write_report
    from study.simulated.runner import simulate

    d = tmp_path_factory.mktemp("memory3")
    db = d / "m3.db"
    simulate(protocol_path=MEMORY3, db=db, participants=3, seed=1, progress=False)
    files = write_report(load_tables(db=db), d / "report")
    return db, d / "report", json.loads(files.results_json.read_text()), files.markdown.read_text()


def test_memory3_report_replays_the_protocols_own_predictors(memory3_report) -> None:
    _, _, doc, md = memory3_report
    assert doc["predictors"]["memory"]["config"] == {
        "kind": "memory",
        "cost": "length",
        "rationality": 30.0,
    }
    assert doc["predictors"]["amnesic"]["config"] == {"kind": "amnesic", "temperature": 0.05}
    assert (
        "Predictor parameters: amnesic: temperature 0.05 (the protocol's "
        "[prediction.amnesic]); memory: cost length, rationality 30 (the protocol's "
        "[prediction.memory])"
    ) in md
    rate = pd.DataFrame(doc["prediction_summary"]).groupby("predictor")["success_rate"].mean()
    # with eq. 9's squared velocity (the paper's default) it was right a few % of the time
    assert rate["memory"] > 0.6


def test_memory3_report_shows_no_paper_values_for_its_three_level_design(memory3_report) -> None:
    _, _, doc, md = memory3_report
    stats = pd.DataFrame(doc["statistics"])
    mode = stats[(stats.analysis == "timing_ancova") & (stats.effect == "mode")].iloc[0]
    assert mode["df1"] == 2 and mode["paper_value"] is None
    assert stats["paper_value"].isna().all()
    assert "paper F" not in md and "paper |t|" not in md and "about 28 s" not in md
    assert "R² = 0.66" not in md and "R² = 0.9 " not in md
    assert (
        md.count(
            "differs from the paper's 2 x 2 x 2 (difficulty: easy, hard; correctness: "
            "right, wrong; mode: timid, aggressive), so the paper's values are not "
            "shown"
        )
        == 2
    )  # timing and prediction


def test_memory3_report_wording(memory3_report) -> None:
    db, _, doc, md = memory3_report
    n = doc["fits"]["timing_ancova"]["n"]
    assert n == 27 and f"this model treats the {n} times as independent" in md
    assert "(9 per participant)" in md and "9-9" not in md
    assert f"memory3 from {db} (stored protocol); content hash" in md
    # no --protocol given: the default file (dragan2013.toml) is not news
    assert not any("dragan2013" in n for n in doc["notes"])


def test_count_sentence_and_paper_values_follow_the_data(tmp_path: Path) -> None:
    from analysis.load import from_frames
    from analysis.report import write_report

    trials = synthetic_tables(3, seed=4, with_samples=False)["trials"]
    files = write_report(from_frames(trials), tmp_path)
    md = files.markdown.read_text()
    assert "this model treats the 24 times as independent" in md
    assert "(8 per participant)" in md
    # the paper's design (2 x 2 x 2): its values are shown, with its own N and df
    assert "(the paper reports R² = 0.66 for N = 64, residual df = 53)" in md
    assert "| effect | df | F | p | partial η² | paper F | paper p |" in md


def test_other_predictors_than_the_papers_get_no_paper_values(tmp_path: Path) -> None:
    from analysis.load import from_frames
    from analysis.report import write_report

    t = synthetic_tables(8, seed=5, rate_hz=5.0)
    files = write_report(
        from_frames(t["trials"], t["samples"]),
        tmp_path,
        predictors={
            "amnesic": {"kind": "amnesic", "temperature": 0.05},
            "memory": {"kind": "memory", "cost": "length", "rationality": 30.0},
        },
    )
    stats = files.results.statistics
    pred = stats[stats.analysis == "prediction_anova"]
    assert pred["paper_value"].isna().all()
    assert (
        stats[(stats.analysis == "timing_ancova") & (stats.effect == "mode")]["paper_value"].iloc[0]
        == 13.2
    )
    md = files.markdown.read_text()
    assert "The predictors replayed differ from the paper's" in md
    assert "memory: cost length, rationality 30 (given by the caller)" in md


def test_a_differing_protocol_file_is_named_only_when_the_user_gave_it(
    memory3_report, protocol_path: Path
) -> None:
    db = memory3_report[0]
    assert load_protocol_info(protocol_path, stored=db, explicit=False).notes == ()
    given = load_protocol_info(protocol_path, stored=db)
    assert any(str(protocol_path) in n and "not used" in n for n in given.notes)

"""A small simulated study into a temporary store, and its report.

Shows the platform end to end without people: four simulated participants (drawn from
``protocols/population.toml``: reaction times, Fitts' law, tremor, learning, opinions) go
through the whole protocol of ``protocols/dragan2013.toml`` - consent, practice runs, the eight
conditions in a counterbalanced order, every questionnaire item - through the same session
engine, control loop and SQLite store as a live study. The analysis package then reads the
store and writes the report (the paper's repeated-measures ANOVAs, figures, HTML and Markdown).
Four participants are too few for the statistics to mean much: ``python -m study simulate
--participants 64`` is the real thing.

Run: ``python examples/03_simulated_study.py``
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from analysis import load_tables
from analysis.report import write_report
from study.simulated import simulate

PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "dragan2013.toml"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "study.db"
        wall = time.perf_counter()
        run = simulate(
            protocol_path=PROTOCOL, db=db, participants=4, seed=1, workers=1, progress=False
        )
        print(
            f"simulated {run.participants} participants: {run.trials} trials,"
            f" {run.ratings} answers, outcomes {run.outcomes} ({time.perf_counter() - wall:.1f} s)"
        )

        wall = time.perf_counter()
        tables = load_tables(db=db)
        report = write_report(tables, Path(tmp) / "report", protocol_path=PROTOCOL)
        print(f"report: {len(report.figures)} figures ({time.perf_counter() - wall:.1f} s)")
        statistics = report.results.statistics
        print(f"{len(statistics)} tests in {report.html.name}; the first few:")
        columns = ["analysis", "effect", "df1", "df2", "statistic", "p"]
        print(statistics[columns].head(4).to_string(index=False))


if __name__ == "__main__":
    main()

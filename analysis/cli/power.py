"""``python -m analysis power``: power of the paper's hypotheses (or, with ``--effect`` /
``--pair``, of any declared contrast: :mod:`analysis.cli.contrast_power`) at several N from a
pilot.

Resamples the study's participants (a pilot store, an export folder, or a simulated population)
with replacement, B times for each N, and runs H1 and H2 in the paper's and the reviewer's forms
on every replicate (see :mod:`analysis.power`). Writes OUT/power.csv (power per test, form and
N with a Wilson 95% CI), OUT/power.json (that, the N needed for 80% power, and the settings) and
OUT/power_curve.png|svg; prints the N-for-80% table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from analysis.cli import contrast_power, fail, friendly, note
from analysis.figures import power_figure, save
from analysis.load import load_tables, task_cells
from analysis.power import bootstrap_power, pilot_cells
from analysis.report.document import jsonable
from study.cli.arguments import float_range, int_range, output_dir

MAX_N = 10_000
MAX_B = 100_000
MAX_WORK = 1_000_000
"""Largest N x B: each resampled participant takes about 640 bytes of design matrices
((B, 8 N, p) floats), 0.64 GB at the limit."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--db", help="the pilot's (or simulated population's) SQLite store")
    src.add_argument("--export-dir", help="a folder written by `python -m study export`")
    parser.add_argument(
        "--out", type=output_dir, required=True, help="output folder (created if needed)"
    )
    parser.add_argument(
        "--n",
        type=int_range(2, MAX_N),
        nargs="+",
        default=[8, 12, 16, 24, 32],
        metavar="N",
        help=f"numbers of participants to evaluate, 2..{MAX_N} (default 8 12 16 24 32)",
    )
    parser.add_argument(
        "--b",
        type=int_range(1, MAX_B),
        default=1000,
        help=f"resampled studies per N, 1..{MAX_B} (default 1000)",
    )
    parser.add_argument(
        "--alpha", type=float_range(0.0, 0.5, above=True), default=0.05, help="significance level"
    )
    parser.add_argument(
        "--seed", type=int_range(0, 2**32 - 1), default=0, help="seed of the resampling"
    )
    parser.add_argument(
        "--successful-only",
        action="store_true",
        help="leave out completed trials that ended without success",
    )
    contrast_power.add_arguments(parser)


@friendly
def main(args: argparse.Namespace) -> int:

    work = max(args.n) * args.b
    if work > MAX_WORK:
        return fail(
            f"--n {max(args.n)} x --b {args.b} = {work:,} resampled participants per N; at most"
            f" {MAX_WORK:,} (lower --b: 1000 gives power to about +-0.03, or lower --n)"
        )
    start = time.perf_counter()
    tables = load_tables(db=args.db, export_dir=args.export_dir)
    if contrast_power.wanted(args):
        res, notes = contrast_power.run(tables, args)
    else:
        cells, found = task_cells(tables.trials, successful_only=args.successful_only)
        if cells.empty:
            return fail(
                f"{tables.source} holds no completed task trials; run a study (or a "
                "simulation) first"
            )
        res = bootstrap_power(
            pilot_cells(cells), ns=args.n, b=args.b, alpha=args.alpha, seed=args.seed
        )
        notes = list(found)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res.table.to_csv(out / "power.csv", index=False, float_format="%.6g")
    fig = save(
        power_figure(res.table),
        out,
        "power_curve",
        "Power against N (Wilson 95% CI); dashed = the paper's form",
    )
    doc = {
        "source": tables.source,
        "participants_in_pilot": res.n_pilot,
        "b": res.b,
        "alpha": res.alpha,
        "seed": res.seed,
        "ns": sorted(set(args.n)),
        "method": (
            "participants resampled with replacement within each between-subject group from "
            "the pilot's condition means; power = share of replicates with p < alpha; Wilson "
            "95% CI"
            if contrast_power.wanted(args)
            else "participants resampled with replacement from the pilot's cell "
            "summaries; power = share of replicates with (Bonferroni) p < alpha in "
            "the hypothesised direction (H2); Wilson 95% CI"
        ),
        "power": res.table.to_dict(orient="records"),
        "n_for_80_percent": res.summary.to_dict(orient="records"),
        "notes": [*notes, *res.notes],
    }
    (out / "power.json").write_text(
        json.dumps(jsonable(doc), indent=1, allow_nan=False), encoding="utf-8"
    )
    for n in doc["notes"]:
        note(n)
    show = res.summary.copy()
    show["n80"] = show["n80"].map(lambda v: f"{v:.0f}" if v == v else f"> {max(args.n)}")
    show["n80_interpolated"] = show["n80_interpolated"].map(lambda v: f"{v:.1f}" if v == v else "")
    sys.stdout.write(show.to_string(index=False) + "\n")
    print(
        f"wrote {out / 'power.csv'}, {out / 'power.json'} and {fig.png.name}/{fig.svg.name} "
        f"in {time.perf_counter() - start:.1f} s ({res.n_pilot} pilot participants, "
        f"B = {res.b} per N)",
        file=sys.stderr,
    )
    return 0

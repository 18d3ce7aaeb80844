"""``python -m analysis anova``: repeated-measures ANOVA on any tidy long-format CSV.

Without covariates: the univariate repeated-measures ANOVA (F(df_E, df_E (n-1)), partial eta
squared, Greenhouse-Geisser epsilon). With ``--covariates``: the paper's factorial ANOVA with
covariates on one row per subject and cell (OLS, sum-to-zero contrasts, type III SS).
With ``--mixed``: a linear mixed model with a random intercept per subject on every row (no
averaging; incomplete subjects are kept), covariates allowed, type III Wald F on Satterthwaite
df (:mod:`analysis.mixed`). Prints one row per effect: effect, df1, df2, F, p, np2 (then for the
RM model eps_gg, p_gg, eps_hf, p_hf and Mauchly's test; for the mixed model the method).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import pandas as pd

from analysis.anova import covariate_anova
from analysis.cli import fail, friendly, note
from analysis.errors import SourceError
from analysis.mixed import mixed_anova
from analysis.rm_anova import rm_anova
from app.files import InputFileError, check_input_file


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--csv", required=True, help="long-format CSV, one row per observation")
    parser.add_argument("--dv", required=True, help="numeric dependent variable column")
    parser.add_argument("--subject", required=True, help="subject (participant) id column")
    parser.add_argument(
        "--within",
        required=True,
        nargs="+",
        metavar="COL",
        help="within-subject factor columns (any number of levels)",
    )
    parser.add_argument(
        "--covariates",
        nargs="+",
        default=[],
        metavar="COL",
        help="numeric covariates: switches to the factorial ANOVA with covariates",
    )
    parser.add_argument(
        "--model",
        choices=["auto", "rm", "factorial"],
        default="auto",
        help="rm = repeated measures, factorial = OLS with covariates "
        "(auto: factorial when covariates are given)",
    )
    parser.add_argument(
        "--ss-type",
        type=int,
        choices=[2, 3],
        default=3,
        help="sums of squares of the factorial model (default 3)",
    )
    parser.add_argument(
        "--mixed",
        action="store_true",
        help="linear mixed model with a random intercept per subject instead "
        "(covariates allowed, Satterthwaite df; uses every row)",
    )
    parser.add_argument(
        "--drop-incomplete",
        action="store_true",
        help="drop subjects lacking cells instead of stopping",
    )
    parser.add_argument("--format", choices=["csv", "json"], default="csv")


MAX_CSV_BYTES = 256 * 2**20
"""Largest CSV read (a study's per-tick samples of 64 participants are about 100 MB)."""


def read_csv(path: str) -> pd.DataFrame:
    """A CSV file with a header row; only a regular file of at most ``MAX_CSV_BYTES``."""
    try:
        check_input_file(path, max_bytes=MAX_CSV_BYTES, what="CSV file")
    except InputFileError as e:
        if not e.path.exists():  # the commands' own wording for a missing file
            raise SourceError(f"file not found: {path}. Check the path.") from None
        raise SourceError(str(e)) from None
    try:
        return pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise SourceError(
            f"{path} is not a readable CSV file ({e}); pass a comma-separated "
            "file with a header row"
        ) from e


@friendly
def main(args: argparse.Namespace) -> int:
    data = read_csv(args.csv)
    if args.mixed:
        if args.model != "auto":
            return fail("--mixed is its own model; leave out --model")
        mres = mixed_anova(
            data, dv=args.dv, subject=args.subject, factors=args.within, covariates=args.covariates
        )
        table = mres.table
        notes = (
            *mres.notes,
            f"linear mixed model, random intercept per subject (REML), "
            f"{mres.n} rows from {mres.n_subjects} subjects; subject variance "
            f"{mres.var_subject:.4g}, residual variance {mres.var_resid:.4g}; type III "
            f"Wald F on {mres.df_method} df",
        )
        return _write(table, notes, args.format)
    model = args.model
    if model == "auto":
        model = "factorial" if args.covariates else "rm"
    if model == "rm" and args.covariates:
        return fail(
            "--covariates need --model factorial (or auto); the repeated-measures model "
            "has no covariates"
        )
    if model == "rm":
        res = rm_anova(
            data,
            dv=args.dv,
            subject=args.subject,
            within=args.within,
            drop_incomplete=args.drop_incomplete,
        )
        table, notes = res.table.drop(columns=["SS", "SS_error"]), res.notes
        notes = (*notes, f"repeated-measures ANOVA, {res.n_subjects} subjects")
    else:
        fres = covariate_anova(
            data,
            dv=args.dv,
            subject=args.subject,
            within=args.within,
            covariates=args.covariates,
            drop_incomplete=args.drop_incomplete,
            ss_type=args.ss_type,
        )
        table = fres.table.drop(columns=["SS"])
        notes = (
            *fres.notes,
            f"factorial OLS ANOVA with covariates, type {fres.ss_type} SS, "
            f"N = {fres.n}, R^2 = {fres.r2:.3f}",
        )
    return _write(table, notes, args.format)


def _plain(v: object) -> object:
    """JSON-ready scalar: numpy scalars unwrapped, NaN (e.g. no Mauchly test for 1 df) -> null."""
    v = v.item() if hasattr(v, "item") else v
    return None if isinstance(v, float) and math.isnan(v) else v


def _write(table: pd.DataFrame, notes: tuple[str, ...], fmt: str) -> int:
    for n in notes:
        note(n)
    if fmt == "json":
        records = [{k: _plain(v) for k, v in r.items()} for r in table.to_dict(orient="records")]
        sys.stdout.write(json.dumps(records, allow_nan=False) + "\n")
    else:
        sys.stdout.write(table.to_csv(index=False, float_format="%.10g"))
    return 0

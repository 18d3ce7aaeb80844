"""``python -m analysis anova``: repeated-measures ANOVA on any tidy long-format CSV.

Without covariates: the univariate repeated-measures ANOVA (F(df_E, df_E (n-1)), partial eta
squared, Greenhouse-Geisser epsilon). With ``--covariates``: the paper's factorial ANOVA with
covariates on one row per subject and cell (OLS, sum-to-zero contrasts, type III SS).
Prints one row per effect: effect, df1, df2, F, p, np2 (then eps_gg, p_gg for the RM model).
"""

from __future__ import annotations

import argparse
import json
import sys

import pandas as pd

from analysis.anova import covariate_anova
from analysis.cli import fail, friendly, note
from analysis.errors import SourceError
from analysis.rm_anova import rm_anova


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--csv", required=True, help="long-format CSV, one row per observation")
    parser.add_argument("--dv", required=True, help="numeric dependent variable column")
    parser.add_argument("--subject", required=True, help="subject (participant) id column")
    parser.add_argument("--within", required=True, nargs="+", metavar="COL",
                        help="within-subject factor columns (any number of levels)")
    parser.add_argument("--covariates", nargs="+", default=[], metavar="COL",
                        help="numeric covariates: switches to the factorial ANOVA with covariates")
    parser.add_argument("--model", choices=["auto", "rm", "factorial"], default="auto",
                        help="rm = repeated measures, factorial = OLS with covariates "
                             "(auto: factorial when covariates are given)")
    parser.add_argument("--ss-type", type=int, choices=[2, 3], default=3,
                        help="sums of squares of the factorial model (default 3)")
    parser.add_argument("--drop-incomplete", action="store_true",
                        help="drop subjects lacking cells instead of stopping")
    parser.add_argument("--format", choices=["csv", "json"], default="csv")


def read_csv(path: str) -> pd.DataFrame:
    try:
        return pd.read_csv(path)
    except FileNotFoundError:
        raise
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise SourceError(f"{path} is not a readable CSV file ({e}); pass a comma-separated "
                          "file with a header row") from e


@friendly
def main(args: argparse.Namespace) -> int:
    data = read_csv(args.csv)
    model = args.model
    if model == "auto":
        model = "factorial" if args.covariates else "rm"
    if model == "rm" and args.covariates:
        return fail("--covariates need --model factorial (or auto); the repeated-measures model "
                    "has no covariates")
    if model == "rm":
        res = rm_anova(data, dv=args.dv, subject=args.subject, within=args.within,
                       drop_incomplete=args.drop_incomplete)
        table, notes = res.table.drop(columns=["SS", "SS_error"]), res.notes
        notes = (*notes, f"repeated-measures ANOVA, {res.n_subjects} subjects")
    else:
        fres = covariate_anova(data, dv=args.dv, subject=args.subject, within=args.within,
                               covariates=args.covariates, drop_incomplete=args.drop_incomplete,
                               ss_type=args.ss_type)
        table = fres.table.drop(columns=["SS"])
        notes = (*fres.notes, f"factorial OLS ANOVA with covariates, type {fres.ss_type} SS, "
                 f"N = {fres.n}, R^2 = {fres.r2:.3f}")
    for n in notes:
        note(n)
    if args.format == "json":
        records = [{k: (v.item() if hasattr(v, "item") else v) for k, v in r.items()}
                   for r in table.to_dict(orient="records")]
        sys.stdout.write(json.dumps(records, allow_nan=True) + "\n")
    else:
        sys.stdout.write(table.to_csv(index=False, float_format="%.10g"))
    return 0

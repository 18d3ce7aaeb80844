"""Repeated-measures correlation (Bakdash & Marusich 2017): the common within-subject
association of two measures taken several times on each subject.

With subject-centred values ``x~ = x - mean_s(x)``, ``y~ = y - mean_s(y)`` (the ANCOVA
``y ~ subject + x``): ``r_rm = sum x~y~ / sqrt(sum x~^2 sum y~^2)`` on ``df = N - k - 1`` for
``N`` observations of ``k`` subjects, ``t = r_rm sqrt(df) / sqrt(1 - r_rm^2)``; 95% CI by Fisher's
z with ``se = 1 / sqrt(df - 3)``, as R's rmcorr and pingouin's ``rm_corr`` compute it.
Unlike Pearson's r on all ``N`` pairs it neither counts a subject's repeated pairs as independent
nor mixes between-subject differences into the association.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import special

from analysis.design import numeric_column, require_columns
from analysis.errors import DesignError

COLUMNS = ["n", "n_subjects", "df", "r", "t", "p", "ci_low", "ci_high"]
Z975 = 1.959963984540054


def rm_corr(data: pd.DataFrame, *, x: str, y: str, subject: str) -> dict[str, float]:
    """Repeated-measures correlation of columns ``x`` and ``y`` (complete pairs only);
    subjects with a single pair carry no within-subject information and are left out."""
    require_columns(data, [x, y, subject])
    d = pd.DataFrame(
        {"s": data[subject].astype(str), "x": numeric_column(data, x), "y": numeric_column(data, y)}
    ).dropna()
    counts = d.groupby("s")["x"].transform("size")
    d = d[counts > 1]
    n, k = len(d), d["s"].nunique()
    df = n - k - 1
    if k < 1 or df < 1:
        raise DesignError(
            f"a repeated-measures correlation needs subjects with two or more "
            f"pairs and N - subjects - 1 >= 1; got {n} pairs from {k} subject(s)"
        )
    xc = (d["x"] - d.groupby("s")["x"].transform("mean")).to_numpy()
    yc = (d["y"] - d.groupby("s")["y"].transform("mean")).to_numpy()
    sxx, syy = float(xc @ xc), float(yc @ yc)
    nan = float("nan")
    if sxx == 0 or syy == 0:
        return {
            "n": n,
            "n_subjects": k,
            "df": float(df),
            "r": nan,
            "t": nan,
            "p": nan,
            "ci_low": nan,
            "ci_high": nan,
        }
    r = max(-1.0, min(1.0, float(xc @ yc) / np.sqrt(sxx * syy)))
    t = r * np.sqrt(df) / np.sqrt(max(1e-300, 1 - r * r))
    p = float(2 * special.stdtr(df, -abs(t)))
    lo = hi = nan
    if df > 3 and abs(r) < 1:
        z, h = np.arctanh(r), Z975 / np.sqrt(df - 3)
        lo, hi = float(np.tanh(z - h)), float(np.tanh(z + h))
    return {
        "n": n,
        "n_subjects": k,
        "df": float(df),
        "r": r,
        "t": float(t),
        "p": p,
        "ci_low": lo,
        "ci_high": hi,
    }


def rm_corr_table(
    data: pd.DataFrame, pairs: Sequence[tuple[str, str]], *, subject: str
) -> pd.DataFrame:
    """One row per ``(measure, versus)`` pair: ``COLUMNS`` plus the pair's names."""
    rows = [
        {
            "measure": a,
            "versus": b,
            "test": "repeated-measures r",
            **rm_corr(data, x=a, y=b, subject=subject),
        }
        for a, b in pairs
    ]
    return pd.DataFrame(rows, columns=["measure", "versus", "test", *COLUMNS])

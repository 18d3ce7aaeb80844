"""Long-format data -> one mean per subject and cell, with the checks every ANOVA needs.

A within-subjects design with factors ``F1..Fk`` (levels ``L1..Lk``) has ``prod(Li)`` cells; each
subject contributes one value per cell. Repeated rows of a subject-cell are averaged (with a note),
missing cells are an error naming who lacks what (or those subjects are dropped, on request).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.errors import DesignError, SchemaError

MAX_LISTED = 10


@dataclass(frozen=True)
class CellData:
    """Cell means of a complete within-subjects design.

    ``values[s, c]`` is subject ``s``'s mean in cell ``c``; cells run over the product of the
    factors' levels with the first factor varying slowest (``itertools.product`` order).
    """

    subjects: tuple[str, ...]
    factors: tuple[str, ...]
    levels: tuple[tuple[str, ...], ...]
    values: np.ndarray
    counts: np.ndarray
    notes: tuple[str, ...]

    @property
    def cells(self) -> list[tuple[str, ...]]:
        return list(itertools.product(*self.levels))

    def to_long(self, *, dv: str = "value", subject: str = "subject") -> pd.DataFrame:
        """The cell means back in long format (one row per subject and cell)."""
        cells = self.cells
        rows = {subject: np.repeat(self.subjects, len(cells))}
        for i, f in enumerate(self.factors):
            rows[f] = [c[i] for c in cells] * len(self.subjects)
        rows[dv] = self.values.ravel()
        return pd.DataFrame(rows)


def require_columns(data: pd.DataFrame, columns: Sequence[str], *, what: str = "data") -> None:
    """Raise SchemaError naming every column of ``columns`` missing from ``data``."""
    if not isinstance(data, pd.DataFrame):
        raise SchemaError(f"{what} must be a pandas DataFrame, got {type(data).__name__}")
    missing = [c for c in columns if c not in data.columns]
    if missing:
        have = ", ".join(map(str, data.columns[:30]))
        raise SchemaError(
            f"{what} has no column(s) {', '.join(map(repr, missing))}; columns present: {have}. "
            "Check the spelling (names are case-sensitive) or pass the right column names."
        )


def numeric_column(data: pd.DataFrame, column: str, *, what: str = "data") -> pd.Series:
    """``data[column]`` as float; a clear SchemaError when it holds non-numeric values."""
    s = data[column]
    if pd.api.types.is_bool_dtype(s):
        return s.astype(float)
    if pd.api.types.is_numeric_dtype(s):
        return s.astype(float)
    conv = pd.to_numeric(s, errors="coerce")
    bad = s[conv.isna() & s.notna()]
    if len(bad):
        examples = ", ".join(f"row {i}: {v!r}" for i, v in list(bad.items())[:5])
        raise SchemaError(
            f"column {column!r} of {what} must be numeric but {len(bad)} value(s) are not "
            f"({examples}). Pass a numeric dependent variable, or clean those rows first."
        )
    return conv.astype(float)


def _levels(s: pd.Series) -> tuple[str, ...]:
    if isinstance(s.dtype, pd.CategoricalDtype):
        present = set(s.dropna().astype(str))
        return tuple(str(c) for c in s.cat.categories if str(c) in present)
    return tuple(sorted(set(s.dropna().astype(str))))


def cell_means(
    data: pd.DataFrame,
    *,
    dv: str,
    subject: str,
    within: Sequence[str],
    drop_incomplete: bool = False,
) -> CellData:
    """Average ``dv`` per subject and cell of the ``within`` factors, checking the design."""
    within = list(within)
    _check_roles(dv, subject, within)
    require_columns(data, [dv, subject, *within])
    notes: list[str] = []
    df = _coded(data, dv=dv, subject=subject, within=within)
    _require_within_subjects(df, within)  # before rows with a missing value are left out
    if df["_y"].isna().any():
        n_nan = int(df["_y"].isna().sum())
        notes.append(f"{n_nan} row(s) with a missing {dv!r} were left out")
        df = df[df["_y"].notna()]
    levels = tuple(_levels(data[f]) for f in within)
    for f, lv in zip(within, levels, strict=True):
        if len(lv) < 2:
            raise DesignError(
                f"factor {f!r} has {len(lv)} level{'s' if len(lv) != 1 else ''} "
                f"({', '.join(lv) or 'none'}); "
                "a factor needs at least two levels - drop it from the design"
            )
    subjects, means, counts = _cell_table(df, levels, dv=dv, notes=notes)
    lacking = np.isnan(means)
    if lacking.any():
        missing = _missing_cells(lacking, subjects, within, levels)
        if not drop_incomplete:
            raise _incomplete(missing, len(subjects), notes)
        keep = ~lacking.any(axis=1)
        notes.append(
            f"dropped {len(missing)} subject(s) with missing cells: {', '.join(list(missing)[:MAX_LISTED])}"
            + (" ..." if len(missing) > MAX_LISTED else "")
        )
        means, counts = means[keep], counts[keep]
        subjects = [s for s, k in zip(subjects, keep, strict=True) if k]
    if len(subjects) < 2:
        raise DesignError(
            f"only {len(subjects)} subject(s) with complete data; a repeated-measures "
            "analysis needs at least two"
        )
    return CellData(
        subjects=tuple(subjects),
        factors=tuple(within),
        levels=levels,
        values=means,
        counts=counts,
        notes=tuple(notes),
    )


def _check_roles(dv: str, subject: str, within: list[str]) -> None:
    if not within:
        raise DesignError("no within-subject factor given; name at least one factor column")
    names = [dv, subject, *within]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DesignError(
            f"column(s) {', '.join(map(repr, dupes))} used twice among the dependent variable, "
            "subject and factors; each role needs its own column"
        )


def _coded(data: pd.DataFrame, *, dv: str, subject: str, within: list[str]) -> pd.DataFrame:
    """Columns ``_s`` (subject), ``_y`` (dv as float) and ``_f0..`` (factor levels as text);
    an empty factor or subject cell raises DesignError."""
    y = numeric_column(data, dv)
    df = pd.DataFrame({"_s": data[subject].astype(str), "_y": y})
    for i, f in enumerate(within):
        if data[f].isna().any():
            rows = list(data.index[data[f].isna()][:5])
            raise DesignError(
                f"factor {f!r} is empty in {int(data[f].isna().sum())} row(s) (e.g. rows {rows}); "
                "fill in the level or drop those rows"
            )
        df[f"_f{i}"] = data[f].astype(str)
    if data[subject].isna().any():
        raise DesignError(
            f"subject column {subject!r} is empty in {int(data[subject].isna().sum())} row(s); "
            "every row needs a subject id"
        )
    return df


def _require_within_subjects(df: pd.DataFrame, within: list[str]) -> None:
    """DesignError for a factor that varies only between subjects."""
    for i, f in enumerate(within):
        per_subject = df.groupby("_s", sort=False)[f"_f{i}"].nunique()
        if df[f"_f{i}"].nunique() > 1 and (per_subject <= 1).all():
            raise DesignError(
                f"factor {f!r} does not vary within subjects (every subject has one level): it "
                "is a between-subjects factor; this repeated-measures analysis takes "
                "within-subject factors only - drop it from --within"
            )


def _cell_table(
    df: pd.DataFrame, levels: tuple[tuple[str, ...], ...], *, dv: str, notes: list[str]
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Subjects (first-seen order), ``(subjects, cells)`` means (NaN: no data) and row counts;
    a note on ``notes`` when a subject-cell had more than one row."""
    keys = ["_s", *[f"_f{i}" for i in range(len(levels))]]
    agg = df.groupby(keys, sort=False)["_y"].agg(["mean", "count"])
    repeated = agg["count"] > 1
    if repeated.any():
        notes.append(
            f"{int(repeated.sum())} subject-cell combination(s) had more than one row "
            f"(up to {int(agg['count'].max())}); {dv!r} was averaged within each"
        )
    subjects = list(dict.fromkeys(df["_s"]))
    full = pd.MultiIndex.from_product([subjects, *levels], names=keys)
    agg = agg.reindex(full)
    n_cells = int(np.prod([len(lv) for lv in levels]))
    means = agg["mean"].to_numpy().reshape(len(subjects), n_cells)
    counts = agg["count"].fillna(0).to_numpy().reshape(len(subjects), n_cells).astype(int)
    return subjects, means, counts


def _missing_cells(
    lacking: np.ndarray,
    subjects: list[str],
    within: list[str],
    levels: tuple[tuple[str, ...], ...],
) -> dict[str, list[str]]:
    """Each incomplete subject and the cells (``f=v & ...``) it lacks."""
    cells = [
        " & ".join(f"{f}={v}" for f, v in zip(within, c, strict=True))
        for c in itertools.product(*levels)
    ]
    return {
        subjects[i]: [cells[j] for j in np.flatnonzero(lacking[i])]
        for i in np.flatnonzero(lacking.any(axis=1))
    }


def _incomplete(missing: dict[str, list[str]], n_subjects: int, notes: list[str]) -> DesignError:
    listed = "; ".join(f"{s} lacks {', '.join(c)}" for s, c in list(missing.items())[:MAX_LISTED])
    more = f" (and {len(missing) - MAX_LISTED} more)" if len(missing) > MAX_LISTED else ""
    return DesignError(
        f"the design is incomplete: {len(missing)} of {n_subjects} subject(s) lack "
        f"cells - {listed}{more}"
        + (f" ({'; '.join(notes)})" if notes else "")
        + ". Collect the missing data, or drop these subjects "
        "(--drop-incomplete / drop_incomplete=True)",
        missing=missing,
    )


def effect_terms(factors: Sequence[str]) -> list[tuple[int, ...]]:
    """All non-empty subsets of factor indices, main effects first, then by order."""
    k = len(factors)
    return [t for r in range(1, k + 1) for t in itertools.combinations(range(k), r)]


def effect_name(factors: Sequence[str], term: Sequence[int]) -> str:
    """``A:B`` style name of an effect (statsmodels' convention)."""
    return ":".join(str(factors[i]) for i in term)

"""Power of any declared contrast -- a factor's main effect or a pair of conditions -- by
resampling a pilot's participants, for a design by factor name.

From each complete pilot participant we keep one mean per within condition and their between
group. A replicate study of ``N`` participants draws ``N / g`` of each of the ``g`` between groups
with replacement (the balanced assignment the schedule makes); ``B`` replicates per ``N``,
all at once as arrays. On each replicate:

- a within factor's main effect: the split-plot F of its contrasts ``Z = Y K`` (equal groups),
  ``F = (N ||mean Z||^2 / q) / (sum ||Z - group mean||^2 / (q (N - g)))`` on ``(q, q (N - g))``;
- a between factor's main effect (one between factor): the one-way ANOVA of the participants'
  means over the conditions, ``F(g - 1, N - g)``;
- a pair of conditions (``factor=level`` for some factors; unnamed within factors averaged):
  paired t on the participants of the pair's group(s) when both sides share their between
  levels, else Welch's t between the two sides' participants.

Power = share of replicates with ``p < alpha``, with Wilson's 95% CI; the pilot is taken as the
population (its effects as true), as in :mod:`analysis.power`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import special

from analysis.design import cell_means
from analysis.errors import DesignError
from analysis.factor_design import FactorDesign
from analysis.power import COLUMNS, PowerResult, paired_t_batch, power_summary, wilson
from analysis.rm_anova import effect_contrasts
from analysis.split_plot import subject_levels

REVIEWER = "reviewer"


@dataclass(frozen=True)
class ContrastPilot:
    """``values[i, c]``: participant ``i``'s mean in within condition ``c`` (product order of
    ``design.within``); ``group[i]``: the index of their between group in ``groups``."""

    design: FactorDesign
    values: np.ndarray
    group: np.ndarray
    groups: tuple[tuple[str, ...], ...]
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Contrast:
    """A factor's main effect (``factor``) or a pair of conditions ``a`` - ``b``."""

    name: str
    factor: str | None = None
    a: Mapping[str, str] | None = None
    b: Mapping[str, str] | None = None


def parse_condition(text: str, design: FactorDesign) -> dict[str, str]:
    """``"intent=shown,mode=timid"`` -> ``{"intent": "shown", "mode": "timid"}``, checked."""
    out = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        factor, sep, level = part.partition("=")
        factor, level = factor.strip(), level.strip()
        if not sep or factor not in design.factors or level not in design.factors[factor]:
            known = "; ".join(f"{f}: {', '.join(v)}" for f, v in design.factors.items())
            raise DesignError(
                f"{part!r} in condition {text!r} is not factor=level of this design ({known})"
            )
        out[factor] = level
    if not out:
        raise DesignError(f"condition {text!r} names no factor=level")
    return out


def pilot_conditions(cells: pd.DataFrame, design: FactorDesign, *, dv: str) -> ContrastPilot:
    """The pilot's complete participants' condition means and groups (``condition_cells``
    output)."""
    if not design.within:
        raise DesignError("no within-subject factor varies in the pilot; nothing to resample")
    data = cells.assign(**{dv: pd.to_numeric(cells[dv], errors="coerce")})
    means = cell_means(
        data, dv=dv, subject="participant", within=design.within, drop_incomplete=True
    )
    levels = subject_levels(
        data, subject="participant", between=design.between, subjects=means.subjects
    )
    keys = [tuple(map(str, r)) for r in levels[list(design.between)].itertuples(index=False)]
    groups = tuple(itertools.product(*(design.factors[f] for f in design.between)))
    lacking = [g for g in groups if g not in keys]
    if lacking or len(means.subjects) < 3:
        raise DesignError(
            f"the pilot has {len(means.subjects)} complete participant(s)"
            + (f" and none in group(s) {lacking}" if lacking else "")
            + "; resampling needs at least 3, and some in every between-subject group"
        )
    notes = tuple(n for n in means.notes if "more than one row" not in n)
    return ContrastPilot(
        design, means.values, np.array([groups.index(k) for k in keys]), groups, notes
    )


def _f_p(f: np.ndarray, df1: float, df2: float) -> np.ndarray:
    return np.where(np.isfinite(f), special.fdtrc(df1, df2, np.nan_to_num(f)), np.nan)


def _within_effect(y: np.ndarray, g: int, contrasts: np.ndarray) -> np.ndarray:
    """p of the split-plot F of ``contrasts`` on ``y`` ``(B, g, n_g, c)``."""
    z = y @ contrasts  # (B, g, n_g, q)
    _, _, n_g, q = z.shape
    n = g * n_g
    zbar = z.mean(axis=(1, 2))
    ss = n * (zbar**2).sum(axis=-1)
    ss_err = ((z - z.mean(axis=2, keepdims=True)) ** 2).sum(axis=(1, 2, 3))
    df2 = q * (n - g)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (ss / q) / (ss_err / df2)
    return _f_p(f, q, df2)


def _between_effect(
    y: np.ndarray, design: FactorDesign, groups: Sequence[tuple[str, ...]], factor: str
) -> np.ndarray:
    """p of the one-way ANOVA of participants' means across ``factor``'s levels."""
    if len(design.between) != 1:
        raise DesignError(
            f"power of the main effect of {factor!r} with several between factors is not "
            "computed; name a pair of conditions (--pair) instead"
        )
    m = y.mean(axis=-1)  # (B, g, n_g)
    g, n_g = m.shape[1], m.shape[2]
    gm = m.mean(axis=2)
    ss_b = n_g * ((gm - gm.mean(axis=1, keepdims=True)) ** 2).sum(axis=1)
    ss_w = ((m - gm[..., None]) ** 2).sum(axis=(1, 2))
    df1, df2 = g - 1, g * n_g - g
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (ss_b / df1) / (ss_w / df2)
    return _f_p(f, df1, df2)


def _side(
    y: np.ndarray, pilot: ContrastPilot, levels: Mapping[str, str]
) -> tuple[np.ndarray, list[int]]:
    """Each sampled participant's mean over the within conditions matching ``levels``
    ``(B, g, n_g)``, and the groups matching its between levels."""
    d = pilot.design
    match = [
        all(levels.get(f, v) == v for f, v in zip(d.within, cond, strict=True))
        for cond in d.conditions
    ]
    groups = [
        i
        for i, key in enumerate(pilot.groups)
        if all(levels.get(f, v) == v for f, v in zip(d.between, key, strict=True))
    ]
    return y[..., np.array(match)].mean(axis=-1), groups


def _pair(
    y: np.ndarray, pilot: ContrastPilot, a: Mapping[str, str], b: Mapping[str, str]
) -> np.ndarray:
    """p of the pair ``a - b``: paired t within shared groups, else Welch's t."""
    va, ga = _side(y, pilot, a)
    vb, gb = _side(y, pilot, b)
    if ga == gb:
        d = (va - vb)[:, ga].reshape(y.shape[0], -1)
        return paired_t_batch(d)[1]
    xa, xb = va[:, ga].reshape(y.shape[0], -1), vb[:, gb].reshape(y.shape[0], -1)
    na, nb = xa.shape[1], xb.shape[1]
    sa, sb = xa.var(axis=1, ddof=1) / na, xb.var(axis=1, ddof=1) / nb
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (xa.mean(axis=1) - xb.mean(axis=1)) / np.sqrt(sa + sb)
        df = (sa + sb) ** 2 / (sa * sa / (na - 1) + sb * sb / (nb - 1))
    return np.where(np.isfinite(t), 2 * special.stdtr(df, -np.abs(t)), np.nan)


def _run(y: np.ndarray, pilot: ContrastPilot, c: Contrast) -> np.ndarray:
    d = pilot.design
    if c.factor is None:
        return _pair(y, pilot, c.a or {}, c.b or {})
    if c.factor in d.between:
        return _between_effect(y, d, pilot.groups, c.factor)
    term = (d.within.index(c.factor),)
    contrasts = effect_contrasts([len(d.factors[f]) for f in d.within], term)
    return _within_effect(y, len(pilot.groups), contrasts)


def _method(pilot: ContrastPilot, c: Contrast) -> str:
    if c.factor is None:
        return "paired t(N - 1) or Welch t between groups, on participant means"
    if c.factor in pilot.design.between:
        return "one-way ANOVA of participant means, F(g - 1, N - g)"
    return "split-plot (RM) F on participant condition means, error df q (N - g)"


def contrast_power(
    pilot: ContrastPilot,
    contrasts: Sequence[Contrast],
    *,
    ns: Sequence[int],
    b: int = 1000,
    alpha: float = 0.05,
    seed: int = 0,
) -> PowerResult:
    """Power of each contrast at each total ``N`` (module docstring); ``N`` is split evenly
    over the between groups (rounded down to whole groups, with a note)."""
    if b < 100:
        raise DesignError(f"B = {b} replicates cannot estimate power; use at least 100")
    g = len(pilot.groups)
    notes = list(pilot.notes)
    uneven = sorted({n for n in ns if n % g})
    if uneven:
        notes.append(f"N of {uneven} rounded down to whole sets of the {g} between-subject groups")
    rng = np.random.default_rng(seed)
    members = [np.flatnonzero(pilot.group == k) for k in range(g)]
    rows = []
    for n in sorted({int(v) for v in ns}):
        n_g = n // g
        if n_g < 2:
            raise DesignError(f"N = {n} leaves fewer than 2 participants in each of {g} groups")
        idx = np.stack([m[rng.integers(0, len(m), size=(b, n_g))] for m in members], axis=1)
        y = pilot.values[idx]  # (B, g, n_g, cells)
        for c in contrasts:
            p = _run(y, pilot, c)
            hits = int((np.nan_to_num(p, nan=1.0) < alpha).sum())
            rows.append(("contrast", c.name, REVIEWER, _method(pilot, c), n_g * g, hits))
    table = pd.DataFrame(rows, columns=["hypothesis", "test", "form", "method", "n", "successes"])
    table.insert(5, "b", b)
    table["power"] = table["successes"] / b
    table["ci_low"], table["ci_high"] = wilson(table["successes"].to_numpy(), b)
    table["alpha"] = alpha
    return PowerResult(
        table=table[COLUMNS],
        summary=power_summary(table),
        n_pilot=len(pilot.group),
        b=b,
        alpha=alpha,
        seed=seed,
        notes=tuple(notes),
    )

"""Power of the paper's hypotheses by resampling participants from a pilot (or simulated) study.

From each participant of the pilot we keep one summary per cell of the 2 x 2 x 2 design (mean
duration, tasks completed before it) and their training covariates. For every ``N`` a replicate
study is ``N`` participants drawn with replacement (``B`` replicates per ``N``, all at once as
arrays), and each test is run on every replicate; its power is the share of replicates with
``p < alpha`` (after Bonferroni where the paper corrects) and, for the directed H2 tests, an
effect in the hypothesised direction. Monte-Carlo 95% CI: Wilson's score interval for ``k`` of ``B``.

Tests (the paper's hypotheses, section 4.1), each in the paper's form and the reviewer's form:

- H1, factors affect performance: main effects of difficulty, correctness and mode and the
  correctness x mode interaction. Paper: the OLS covariate model on ``8N`` times,
  ``F(1, 8N - 8 - k)`` (for one df, ``F = b_j^2 / (MSE (X'X)^-1_jj)``, the type III test).
  Reviewer: the repeated-measures F on participant cell means, ``F(1, N - 1) = t^2`` of each
  participant's contrast score. (A mixed model per replicate is too slow for ``5 B`` fits; in a
  balanced design it differs from this test only by pooling the within-participant error.)
- H2, aggressive better on Hard&Right and timid on Easy&Wrong: the two planned paired t(N - 1)
  tests (Bonferroni over 2), already on one difference per participant, so both forms coincide;
  their conjunction (both significant in the paper's direction); and the post-hoc "when wrong,
  timid beats aggressive": paper ``t(2N - 1)`` on participant x difficulty pairs, reviewer
  ``t(N - 1)`` on participant means (Bonferroni over the family's 3 tests).

Resampling a pilot treats its participants as the population: the pilot's effects are taken as
true (optimistic when the pilot over-estimates them) and a pilot of ``P`` people has variance
``(P - 1) / P`` of its sample variance.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import special

from analysis.errors import DesignError
from analysis.timing import FACTORS, LEVELS, design_levels

DEFAULT_NS = (8, 12, 16, 24, 32)
DEFAULT_B = 1000
CELLS = list(itertools.product(*(LEVELS[f] for f in FACTORS)))
"""The 8 cells, difficulty slowest, mode fastest."""
SUBJECT_COVARIATES = ("training_time_s", "baseline_rating")
PRACTICE = "tasks_completed"
PAPER, REVIEWER, BOTH = "as in the paper", "reviewer", "both (participant-level already)"
COLUMNS = [
    "hypothesis",
    "test",
    "form",
    "method",
    "n",
    "b",
    "successes",
    "power",
    "ci_low",
    "ci_high",
    "alpha",
]
SUMMARY_COLUMNS = ["hypothesis", "test", "form", "n80", "n80_interpolated", "power_at_max_n"]


@dataclass(frozen=True)
class PilotCells:
    """Per-participant cell summaries: ``durations[i, c]`` for ``CELLS[c]``; ``practice[i, c]``
    tasks completed before that cell (or None); ``covariates[i, j]`` participant-level ones."""

    participants: tuple[str, ...]
    durations: np.ndarray
    practice: np.ndarray | None
    covariates: np.ndarray
    covariate_names: tuple[str, ...]
    notes: tuple[str, ...] = ()


def pilot_cells(cells: pd.DataFrame) -> PilotCells:
    """Summaries of ``task_cells`` output (complete participants of the paper's design only)."""
    lv = design_levels(cells)
    if lv != {f: LEVELS[f] for f in FACTORS}:
        found = "; ".join(f"{f}: {', '.join(v)}" for f, v in lv.items())
        raise DesignError(
            f"the power analysis tests the paper's hypotheses and needs its 2 x 2 x "
            f"2 design ({found} found); run it on a study of dragan2013's design, or name "
            "the contrasts to power (--effect FACTOR, --pair CONDITION CONDITION)"
        )
    notes: list[str] = []
    key = list(FACTORS)
    wide = cells.pivot_table(
        index="participant", columns=key, values="duration_s", aggfunc="mean", observed=True
    ).reindex(columns=CELLS)
    complete = wide.notna().all(axis=1)
    if not complete.all():
        notes.append(
            f"left out {int((~complete).sum())} participant(s) lacking a cell: "
            + ", ".join(map(str, wide.index[~complete]))
        )
    wide = wide[complete]
    if len(wide) < 3:
        raise DesignError(
            f"{len(wide)} participant(s) with every cell; resampling needs at "
            "least 3 (more make the estimate less dependent on a few people)"
        )
    people = list(wide.index)
    practice = None
    if PRACTICE in cells.columns and cells[PRACTICE].notna().all():
        practice = (
            cells.pivot_table(
                index="participant", columns=key, values=PRACTICE, aggfunc="mean", observed=True
            )
            .reindex(index=people, columns=CELLS)
            .to_numpy(dtype=float)
        )
    else:
        notes.append(f"covariate {PRACTICE!r} missing: the paper-form model leaves it out")
    covs, names = [], []
    for c in SUBJECT_COVARIATES:
        if c in cells.columns and cells[c].notna().all():
            v = cells.groupby("participant")[c].mean().reindex(people).to_numpy(dtype=float)
            if np.ptp(v) > 0:
                covs.append(v)
                names.append(c)
                continue
        notes.append(f"covariate {c!r} missing or constant: the paper-form model leaves it out")
    return PilotCells(
        participants=tuple(map(str, people)),
        durations=wide.to_numpy(dtype=float),
        practice=practice,
        covariates=np.column_stack(covs) if covs else np.zeros((len(people), 0)),
        covariate_names=tuple(names),
        notes=tuple(notes),
    )


def _sign_vector(factor: str) -> np.ndarray:
    """+1/-1 per cell: second level of ``factor`` (hard, wrong, aggressive) = +1."""
    i = FACTORS.index(factor)
    return np.array([1.0 if c[i] == LEVELS[factor][1] else -1.0 for c in CELLS])


EFFECTS = {
    "difficulty": _sign_vector("difficulty"),
    "correctness": _sign_vector("correctness"),
    "mode": _sign_vector("mode"),
    "correctness:mode": _sign_vector("correctness") * _sign_vector("mode"),
}


def _cell(dif: str, cor: str, mode: str) -> int:
    return CELLS.index((dif, cor, mode))


def paired_t_batch(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided paired t test along the last axis: ``(t, p)`` with ``n - 1`` df."""
    n = d.shape[-1]
    sd = d.std(axis=-1, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d.mean(axis=-1) / (sd / np.sqrt(n))
    p = np.where(np.isfinite(t), 2 * special.stdtr(n - 1, -np.abs(t)), np.nan)
    return t, p


def ancova_batch(
    y: np.ndarray, practice: np.ndarray | None, covariates: np.ndarray, effects: Sequence[str]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The paper's covariate model on each replicate (``y``: ``(B, N, 8)``; covariates
    ``(B, N, k)``; practice ``(B, N, 8)``): per effect ``(F, p)`` on ``8N - 8 - k`` df."""
    b, n, _ = y.shape
    base = [np.ones(8)]
    names = ["difficulty", "correctness", "mode"]
    s = {f: _sign_vector(f) for f in names}
    cols = {f: s[f] for f in names}
    for r in (2, 3):
        for combo in itertools.combinations(names, r):
            cols[":".join(combo)] = np.prod([s[f] for f in combo], axis=0)
    fixed = np.column_stack(base + list(cols.values()))  # (8, 8), orthogonal
    x_parts = [np.broadcast_to(np.tile(fixed, (n, 1)), (b, 8 * n, 8))]
    if covariates.shape[-1]:
        cov = np.repeat(covariates, 8, axis=1)  # (B, 8N, k)
        x_parts.append(cov - cov.mean(axis=1, keepdims=True))
    if practice is not None:
        pr = practice.reshape(b, 8 * n, 1)
        x_parts.append(pr - pr.mean(axis=1, keepdims=True))
    x = np.concatenate(x_parts, axis=2)
    yy = y.reshape(b, 8 * n)
    xtx = np.einsum("bij,bik->bjk", x, x)
    inv = np.linalg.pinv(xtx)
    beta = np.einsum("bjk,bk->bj", inv, np.einsum("bij,bi->bj", x, yy))
    resid = yy - np.einsum("bij,bj->bi", x, beta)
    df = 8 * n - x.shape[2]
    if df <= 0:
        raise DesignError(
            f"N = {n} participants give {8 * n} times for {x.shape[2]} "
            "parameters; choose a larger N"
        )
    mse = (resid**2).sum(axis=1) / df
    out = {}
    order = list(cols)
    for e in effects:
        j = 1 + order.index(e)
        with np.errstate(divide="ignore", invalid="ignore"):
            f = beta[:, j] ** 2 / (mse * inv[:, j, j])
        out[e] = (f, np.where(np.isfinite(f), special.fdtrc(1, df, f), np.nan))
    return out


@dataclass(frozen=True)
class PowerTest:
    """One test: ``run(sample) -> (p, estimate)`` per replicate. A replicate counts when
    ``bonferroni * p < alpha`` and, if ``direction`` is +1 or -1, the estimate has that sign."""

    hypothesis: str
    name: str
    form: str
    method: str
    run: Callable[[_Sample], tuple[np.ndarray, np.ndarray]]
    bonferroni: int = 1
    direction: int = 0


@dataclass(frozen=True)
class _Sample:
    y: np.ndarray  # (B, N, 8)
    practice: np.ndarray | None  # (B, N, 8)
    covariates: np.ndarray  # (B, N, k)
    cache: dict[str, object]


def _rm_effect(effect: str) -> Callable[[_Sample], tuple[np.ndarray, np.ndarray]]:
    def run(s: _Sample) -> tuple[np.ndarray, np.ndarray]:
        score = s.y @ EFFECTS[effect] / 4  # each participant's contrast (difference of means)
        p = paired_t_batch(score)[1]
        return p, score.mean(axis=-1)

    return run


def _ancova_effect(effect: str) -> Callable[[_Sample], tuple[np.ndarray, np.ndarray]]:
    def run(s: _Sample) -> tuple[np.ndarray, np.ndarray]:
        if "ancova" not in s.cache:
            s.cache["ancova"] = ancova_batch(s.y, s.practice, s.covariates, list(EFFECTS))
        p = s.cache["ancova"][effect][1]  # type: ignore[index]
        return p, np.full(p.shape, np.nan)

    return run


def _planned(dif: str, cor: str) -> Callable[[_Sample], tuple[np.ndarray, np.ndarray]]:
    def run(s: _Sample) -> tuple[np.ndarray, np.ndarray]:
        d = s.y[..., _cell(dif, cor, "aggressive")] - s.y[..., _cell(dif, cor, "timid")]
        return paired_t_batch(d)[1], d.mean(axis=-1)

    return run


def _wrong_posthoc(
    *, participant_means: bool
) -> Callable[[_Sample], tuple[np.ndarray, np.ndarray]]:
    def run(s: _Sample) -> tuple[np.ndarray, np.ndarray]:
        d = np.stack(
            [
                s.y[..., _cell(dif, "wrong", "aggressive")] - s.y[..., _cell(dif, "wrong", "timid")]
                for dif in LEVELS["difficulty"]
            ],
            axis=-1,
        )  # (B, N, 2)
        d = d.mean(axis=-1) if participant_means else d.reshape(d.shape[0], -1)
        return paired_t_batch(d)[1], d.mean(axis=-1)

    return run


def default_tests() -> list[PowerTest]:
    """H1 and H2 in the paper's and the reviewer's forms (see the module docstring)."""
    tests = []
    for e in EFFECTS:
        tests.append(
            PowerTest("H1", e, PAPER, "OLS covariate model, F(1, 8N - 8 - k)", _ancova_effect(e))
        )
        tests.append(
            PowerTest(
                "H1", e, REVIEWER, "RM ANOVA on participant cell means, F(1, N - 1)", _rm_effect(e)
            )
        )
    tests += [
        PowerTest(
            "H2",
            "Hard&Right: aggressive - timid",
            BOTH,
            "paired t(N - 1), Bonferroni over 2, aggressive faster",
            _planned("hard", "right"),
            2,
            -1,
        ),
        PowerTest(
            "H2",
            "Easy&Wrong: aggressive - timid",
            BOTH,
            "paired t(N - 1), Bonferroni over 2, timid faster",
            _planned("easy", "wrong"),
            2,
            +1,
        ),
        PowerTest(
            "H2",
            "wrong: aggressive - timid (post-hoc)",
            PAPER,
            "paired t(2N - 1) on participant x difficulty pairs, Bonferroni over 3, timid faster",
            _wrong_posthoc(participant_means=False),
            3,
            +1,
        ),
        PowerTest(
            "H2",
            "wrong: aggressive - timid (post-hoc)",
            REVIEWER,
            "paired t(N - 1) on participant means, Bonferroni over 3, timid faster",
            _wrong_posthoc(participant_means=True),
            3,
            +1,
        ),
    ]
    return tests


BOTH_PLANNED = "both planned comparisons"


def wilson(
    k: np.ndarray | int, n: int, *, z: float = 1.959963984540054
) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval of a binomial proportion ``k / n``: exactly 0 below ``k = 0`` and
    1 above ``k = n`` (the formula leaves rounding residue there, e.g. 2.2e-19), and always
    around ``k / n``."""
    k = np.asarray(k, dtype=float)
    phat = k / n
    den = 1 + z * z / n
    centre = (phat + z * z / (2 * n)) / den
    half = z * np.sqrt(phat * (1 - phat) / n + z * z / (4 * n * n)) / den
    lo = np.where(k <= 0, 0.0, np.clip(centre - half, 0.0, phat))
    hi = np.where(k >= n, 1.0, np.clip(centre + half, phat, 1.0))
    return lo, hi


@dataclass(frozen=True)
class PowerResult:
    """``table``: power per test, form and N (``COLUMNS``); ``summary``: N for 80% power."""

    table: pd.DataFrame
    summary: pd.DataFrame
    n_pilot: int
    b: int
    alpha: float
    seed: int
    notes: tuple[str, ...]


def n80(ns: np.ndarray, power: np.ndarray, target: float = 0.8) -> tuple[float, float]:
    """Smallest N of the grid reaching ``target``, and N linearly interpolated between the grid
    points around it (NaN when the smallest N already reaches it or no N does)."""
    hit = np.flatnonzero(power >= target)
    if not len(hit):
        return np.nan, np.nan
    i = hit[0]
    if i == 0:
        return float(ns[0]), np.nan
    lo, hi = power[i - 1], power[i]
    return float(ns[i]), float(ns[i - 1] + (target - lo) / (hi - lo) * (ns[i] - ns[i - 1]))


def power_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per hypothesis, test and form of a power ``table``: the smallest N with power >= 0.8
    (:func:`n80`, and interpolated) and the power at the largest N."""
    rows = []
    for (h, name, form), g in table.groupby(["hypothesis", "test", "form"], sort=False):
        g = g.sort_values("n")
        n_80, interp = n80(g["n"].to_numpy(dtype=float), g["power"].to_numpy())
        rows.append(
            {
                "hypothesis": h,
                "test": name,
                "form": form,
                "n80": n_80,
                "n80_interpolated": interp,
                "power_at_max_n": float(g["power"].iloc[-1]),
            }
        )
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)


def bootstrap_power(
    pilot: PilotCells,
    *,
    ns: Sequence[int] = DEFAULT_NS,
    b: int = DEFAULT_B,
    alpha: float = 0.05,
    seed: int = 0,
    tests: Sequence[PowerTest] | None = None,
) -> PowerResult:
    """Power of each test at each ``N`` from ``b`` resampled studies (see the module doc)."""
    if b < 100:
        raise DesignError(
            f"B = {b} replicates cannot estimate power; use at least 100 (1000 "
            "gives a Monte-Carlo standard error of at most 0.016)"
        )
    if not ns or min(ns) < 3:
        raise DesignError(f"sample sizes must be at least 3 participants, got {list(ns)}")
    if not 0 < alpha < 1:
        raise DesignError(f"alpha must lie in (0, 1), got {alpha}")
    tests = list(tests) if tests is not None else default_tests()
    rng = np.random.default_rng(seed)
    rows = []
    for n in sorted(set(int(v) for v in ns)):
        idx = rng.integers(0, len(pilot.participants), size=(b, n))
        sample = _Sample(
            pilot.durations[idx],
            None if pilot.practice is None else pilot.practice[idx],
            pilot.covariates[idx],
            {},
        )
        planned_hits = []
        for t in tests:
            p, est = t.run(sample)
            p_adj = np.minimum(1.0, p * t.bonferroni)
            sig = np.nan_to_num(p_adj, nan=1.0) < alpha
            if t.direction:
                sig &= np.sign(est) == t.direction
            if t.hypothesis == "H2" and t.form == BOTH:
                planned_hits.append(sig)
            rows.append((t.hypothesis, t.name, t.form, t.method, n, int(sig.sum())))
        if len(planned_hits) == 2:
            rows.append(
                (
                    "H2",
                    BOTH_PLANNED,
                    BOTH,
                    "both planned t(N - 1) significant in the "
                    "hypothesised direction (Bonferroni over 2)",
                    n,
                    int((planned_hits[0] & planned_hits[1]).sum()),
                )
            )
    table = pd.DataFrame(rows, columns=["hypothesis", "test", "form", "method", "n", "successes"])
    table.insert(5, "b", b)
    table["power"] = table["successes"] / b
    table["ci_low"], table["ci_high"] = wilson(table["successes"].to_numpy(), b)
    table["alpha"] = alpha
    return PowerResult(
        table=table[COLUMNS],
        summary=power_summary(table),
        n_pilot=len(pilot.participants),
        b=b,
        alpha=alpha,
        seed=seed,
        notes=pilot.notes,
    )

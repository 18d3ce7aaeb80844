"""Run a sweep: every setting of the grid through simulated participants, each into its own
store, then judge them by the paper's criteria (``study.sweep.criteria``).

Every setting sees the same simulated people (same ``seed``: common random numbers), so
differences between settings are the arbitration's, not the draw's. The protocol's current
settings are always in the grid, so every sweep also says whether today's values meet the
criteria (both run in one store, ``today.db``: they are the protocol as written). Stores live
in ``out/stores/<setting>.db`` (the protocol's two modes at another ``D``:
``today-D<D>.db``): a sweep run again with the same arguments keeps the settings already done and continues an interrupted one (``simulate(resume=True)``).
With ``engine="dask"`` all settings run on one cluster (one ``LocalCluster``, or the scheduler
at ``scheduler``), connected once.
"""

from __future__ import annotations

import sys
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from study.simulated import SimulationReport, simulate
from study.simulated.dask_engine import connect
from study.simulated.population import DEFAULT_POPULATION_PATH
from study.store import Store
from study.sweep.criteria import Criteria, Measure, choose, measure
from study.sweep.errors import SweepError
from study.sweep.grid import (
    AGGRESSIVE,
    TIMID,
    Setting,
    check_D,
    current_settings,
    protocol_D,
    write_variant,
)


@dataclass(frozen=True)
class SweepResult:
    """Every setting's evidence, the paper's picks and today's values judged."""

    measures: list[Measure]
    criteria: Criteria
    current: dict[str, Setting]
    saturation: float
    participants: int
    seed: int
    protocol: str
    chosen: dict[str, Measure | None] = field(default_factory=dict)
    errors: list[str] = field(default_factory=list)

    def of(self, setting: Setting) -> Measure:
        return next(m for m in self.measures if m.setting == setting)

    def verdict(self) -> dict[str, Any]:
        """Whether today's values pass, and whether they are the criterion's pick."""
        out: dict[str, Any] = {}
        for mode in (TIMID, AGGRESSIVE):
            today = self.of(self.current[mode])
            chosen = self.chosen.get(mode)
            out[mode] = {
                "setting": self.current[mode].label,
                "passes": today.passes,
                "rate": round(today.rate, 4),
                "time_lost_s": today.row()["time_lost_s"],
                "is_choice": chosen is not None and chosen.setting == today.setting,
                "choice": None if chosen is None else chosen.setting.label,
            }
        return out


def sweep(
    *,
    protocol_path: Path,
    out: Path,
    grid: list[Setting],
    participants: int,
    seed: int,
    criteria: Criteria,
    engine: str = "local",
    workers: int = 1,
    scheduler: str | None = None,
    population_path: Path = DEFAULT_POPULATION_PATH,
    progress: bool = True,
    confidence_D: tuple[float, ...] = (),
) -> SweepResult:
    """Simulate ``participants`` people under every setting of ``grid`` (plus the protocol's
    own settings, and its two modes at every ``D`` of ``confidence_D``) and judge each by
    ``criteria``; writes variants and stores under ``out``."""

    text = Path(protocol_path).read_text(encoding="utf-8")
    current_timid, current_aggressive, saturation = current_settings(text)
    current = {current_timid, current_aggressive}
    settings = _settings(text, grid, current=(current_timid, current_aggressive), D=confidence_D)
    (out / "protocols").mkdir(parents=True, exist_ok=True)
    (out / "stores").mkdir(parents=True, exist_ok=True)
    errors: list[str] = []
    with ExitStack() as stack:
        client = None
        if engine == "dask":
            client = connect(scheduler=scheduler, workers=workers, stack=stack)
        bar = stack.enter_context(
            tqdm(
                total=len(settings),
                unit="setting",
                desc="sweep",
                file=sys.stderr,
                disable=not progress,
            )
        )
        for setting in settings:
            db = _store(out, setting, current=current)
            if _at_protocol_D(setting) in current and _at_protocol_D(setting) != current_timid:
                bar.update(1)  # the protocol's aggressive runs in the store of its timid
                continue
            variant = (
                Path(protocol_path)
                if setting in current
                else write_variant(text, setting, saturation=saturation, folder=out / "protocols")
            )
            report = simulate(
                protocol_path=variant,
                db=db,
                participants=participants,
                seed=seed,
                workers=workers,
                population_path=population_path,
                progress=progress,
                resume=db.exists(),
                engine=engine,
                client=client,
            )
            errors += _errors(setting, report)
            bar.update(1)
    measures = []
    for setting in settings:
        with Store.open_readonly(_store(out, setting, current=current)) as store:
            measures.append(measure(store, setting, saturation=saturation, criteria=criteria))
    return SweepResult(
        measures=measures,
        criteria=criteria,
        current={TIMID: current_timid, AGGRESSIVE: current_aggressive},
        saturation=saturation,
        participants=participants,
        seed=seed,
        protocol=str(protocol_path),
        chosen={mode: choose(measures, mode) for mode in (TIMID, AGGRESSIVE)},
        errors=errors,
    )


def _settings(
    text: str, grid: list[Setting], *, current: tuple[Setting, Setting], D: tuple[float, ...]
) -> list[Setting]:
    """The grid, then the protocol's own two settings if the grid lacks them, then those two
    at every confidence ``D`` other than the protocol's own."""
    settings = list(grid)
    settings += [c for c in current if c not in settings]
    if D:
        own = protocol_D(text)
        for d in check_D(D):
            if own != d:
                settings += [c.at(d) for c in current]
    return settings


def _errors(setting: Setting, report: SimulationReport) -> list[str]:
    """The participants' errors of one setting's run, each named by the setting; a store that
    took no more writes stops the sweep (``SweepError``: run it again to continue)."""
    if report.error is not None:
        raise SweepError(
            f"{setting.label}: the store took no more writes ({report.error}); fix it "
            "and run the same sweep again to continue"
        )
    return [f"{setting.label}: {e}" for e in report.errors]


def _at_protocol_D(setting: Setting) -> Setting:
    """``setting`` at the protocol's own ``D``."""
    return Setting(setting.mode, setting.params)


def _store(out: Path, setting: Setting, *, current: set[Setting]) -> Path:
    """Where ``setting``'s participants are stored: today's two settings are one protocol, the
    one as written, so they share ``today.db``; at another ``D`` they share ``today-D<D>.db``."""
    if _at_protocol_D(setting) in current:
        name = "today.db" if setting.D is None else f"today-D{setting.D:g}.db"
    else:
        name = f"{setting.slug}.db"
    return out / "stores" / name

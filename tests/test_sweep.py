"""``python -m study sweep``: a tiny grid on a 2-worker Dask ``LocalCluster`` through the CLI,
and the pieces it is built from (grid, protocol variants, criteria, picks) on their own.

The end-to-end run uses the paper's protocol with 20 s trials and one training run, two
participants, one timid and one aggressive setting besides today's: it checks the files the
sweep writes agree with each other and with the stores, and that running it again continues
(keeps every store) instead of starting over.
"""

from __future__ import annotations

import csv
import json
import re
import tomllib
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from study.__main__ import main as study_main
from study.protocol import load_protocol
from study.sweep import (
    Criteria,
    Measure,
    SweepGridError,
    SweepProtocolError,
    aggressive,
    choose,
    current_settings,
    make_grid,
    measure,
    timid,
    variant_text,
)
from study.sweep.grid import check_D
from tests.protocol_copies import PAPER_PROTOCOL, short_protocol

PAPER = PAPER_PROTOCOL.read_text(encoding="utf-8")


def test_the_protocols_current_settings_are_read() -> None:
    t, a, saturation = current_settings(PAPER)
    assert t == timid(0.5) and a == aggressive(0.4, 0.9) and saturation == 0.7


def test_a_variant_changes_one_mode_and_still_loads(tmp_path: Path) -> None:
    text = variant_text(PAPER, aggressive(0.2, 1.0), saturation=0.7)
    assert text.count("\n") == PAPER.count("\n")
    path = tmp_path / "v.toml"
    path.write_text(text, encoding="utf-8")
    modes = tomllib.loads(text)["modes"]
    assert modes["aggressive"]["arbitration"] == {
        "kind": "aggressive",
        "threshold": 0.2,
        "alpha_high": 1.0,
    }
    assert modes["timid"] == tomllib.loads(PAPER)["modes"]["timid"]
    modes_loaded = {m.name: dict(m.arbitration or {}) for m in load_protocol(path).modes}
    assert modes_loaded["aggressive"] == {"kind": "aggressive", "threshold": 0.2, "alpha_high": 1.0}


def test_a_protocol_without_an_inline_arbitration_is_refused() -> None:
    text = PAPER.replace(
        'arbitration = { kind = "timid", alpha_max = 0.5, saturation = 0.7 }',
        '[modes.timid.arbitration]\nkind = "timid"\nalpha_max = 0.5\nsaturation = 0.7',
    )
    with pytest.raises(SweepProtocolError, match="inline table"):
        variant_text(text, timid(0.3), saturation=0.7)


def test_a_D_variant_changes_only_the_confidence_and_still_loads(tmp_path: Path) -> None:
    text = variant_text(PAPER, timid(0.5).at(0.2), saturation=0.7)
    assert text.count("\n") == PAPER.count("\n")
    doc, paper = tomllib.loads(text), tomllib.loads(PAPER)
    assert doc["confidence"] == {**paper["confidence"], "D": 0.2}
    assert doc["modes"] == paper["modes"]  # the protocol's own modes, both
    path = tmp_path / "v.toml"
    path.write_text(text, encoding="utf-8")
    assert dict(load_protocol(path).confidence)["D"] == 0.2
    assert timid(0.5).at(0.2).label == "timid alpha_max=0.5 D=0.2"
    assert timid(0.5).at(0.2) != timid(0.5)


def test_a_D_sweep_needs_a_distance_confidence_and_positive_values() -> None:
    text = PAPER.replace('kind = "distance"', 'kind = "probability"', 1)
    text = re.sub(r"(?m)^D = .*\n", "", text, count=1)
    with pytest.raises(SweepProtocolError, match="distance"):
        variant_text(text, timid(0.5).at(0.3), saturation=0.7)
    with pytest.raises(SweepGridError, match="D: 0 is out of range"):
        check_D((0.3, 0.0))
    assert check_D((0.4, 0.2, 0.4)) == (0.2, 0.4)


def test_grid_values_are_checked_before_anything_runs() -> None:
    assert len(make_grid()) == 5 + 9
    with pytest.raises(SweepGridError, match="alpha_max: 1 is out of range"):
        make_grid(timid_alpha_max=(0.5, 1.0))
    with pytest.raises(SweepGridError, match="at least one"):
        make_grid(aggressive_threshold=())


def trial(**kw: Any) -> SimpleNamespace:
    base = dict(
        participant="p1",
        step=1,
        attempt=1,
        phase="task",
        status="completed",
        mode="timid",
        difficulty="hard",
        correctness="right",
        success=True,
        duration_s=10.0,
    )
    return SimpleNamespace(**{**base, **kw})


class FakeStore:
    def __init__(self, trials: list[SimpleNamespace]) -> None:
        self._trials = trials

    def trials(self) -> list[SimpleNamespace]:
        return self._trials


def test_criteria_and_picks() -> None:
    criteria = Criteria(min_hard_completion=0.75, min_wrong_corrected=0.5, max_time_lost_s=5)
    hard = [trial(step=k, success=k != 3) for k in range(4)]  # 3 of 4 hard trials completed
    hard += [trial(step=9, difficulty="easy", success=False)]  # easy ones do not count
    hard += [trial(step=8, phase="training", mode="none", success=False)]
    m = measure(FakeStore(hard), timid(0.3), saturation=0.7, criteria=criteria)
    assert (m.trials, m.rate, m.passes) == (4, 0.75, True)
    assert m.help == pytest.approx(0.3 * (1 - 0.35))

    redo = [trial(step=1, attempt=1, success=False), trial(step=1, attempt=2, success=True)]
    assert measure(FakeStore(redo), timid(0.3), saturation=0.7, criteria=criteria).rate == 1.0

    wrong = [
        trial(mode="aggressive", correctness="wrong", step=1, duration_s=16.0),
        trial(mode="aggressive", correctness="wrong", step=2, success=False),
        trial(mode="aggressive", correctness="right", step=3, duration_s=10.0),
    ]
    m = measure(FakeStore(wrong), aggressive(0.4, 0.9), saturation=0.7, criteria=criteria)
    assert (m.rate, m.time_lost_s, m.passes) == (0.5, 6.0, False)  # 6 s lost > 5 s

    def fake(setting: Any, passes: bool, help_: float) -> Measure:
        return Measure(setting, help_, 1, 1, 1.0, None, passes)

    ms = [
        fake(timid(0.2), False, 0.1),
        fake(timid(0.3), True, 0.2),
        fake(timid(0.5), True, 0.3),
        fake(aggressive(0.2, 1.0), False, 0.8),
        fake(aggressive(0.4, 0.9), True, 0.5),
        fake(aggressive(0.6, 0.9), True, 0.4),
    ]
    assert choose(ms, "timid").setting == timid(0.3)  # least help that passes
    assert choose(ms, "aggressive").setting == aggressive(0.4, 0.9)  # most help that passes
    assert choose(ms[:1], "timid") is None
    # another D's settings are evidence, never a pick (their help is on another scale)
    ms.append(fake(aggressive(0.4, 0.9).at(0.2), True, 0.9))
    assert choose(ms, "aggressive").setting == aggressive(0.4, 0.9)


@pytest.mark.slow
def test_sweep_cli_on_a_two_worker_local_cluster(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    protocol = short_protocol(tmp_path, training_runs=1)
    out = tmp_path / "sweep"
    argv = [
        "sweep",
        "--protocol",
        str(protocol),
        "--out",
        str(out),
        "--participants",
        "2",
        "--seed",
        "3",
        "--timid-alpha-max",
        "0.3",
        "--aggressive-threshold",
        "0.6",
        "--aggressive-alpha-high",
        "0.9",
        "--confidence-D",
        "0.35",
        "--engine",
        "dask",
        "--workers",
        "2",
        "--no-progress",
    ]
    code = study_main(argv)
    printed, err = capsys.readouterr()
    assert code == 0, err
    summary = json.loads(printed.strip().splitlines()[-1])
    assert summary["settings"] == 6 and summary["errors"] == []
    assert "help" in printed and "passes" in printed  # the table
    evidence = json.loads((out / "sweep.json").read_text())
    assert evidence["criteria"] == Criteria().as_dict()
    assert evidence["today"] == summary["today"]
    with (out / "sweep.csv").open() as f:
        table = list(csv.DictReader(f))
    assert [
        (r["mode"], r["alpha_max"], r["threshold"], r["alpha_high"], r["D"]) for r in table
    ] == [
        ("timid", "0.3", "", "", ""),
        ("aggressive", "", "0.6", "0.9", ""),
        ("timid", "0.5", "", "", ""),
        ("aggressive", "", "0.4", "0.9", ""),
        ("timid", "0.5", "", "", "0.35"),  # the protocol's own modes at another D
        ("aggressive", "", "0.4", "0.9", "0.35"),
    ]
    for row in table:  # two participants, two trials each in the judged cells
        assert (row["participants"], row["trials"]) == ("2", "4")
    chosen = tomllib.loads((out / "chosen.toml").read_text())  # valid TOML
    for mode in ("timid", "aggressive"):
        pick = evidence["chosen"][mode]
        if pick is None:
            assert "arbitration" not in chosen["modes"][mode]
        else:
            assert chosen["modes"][mode]["arbitration"]["kind"] == mode
            assert summary["today"][mode]["choice"] is not None
    assert (out / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    stores = sorted(p.name for p in (out / "stores").glob("*.db"))
    assert stores == [
        "aggressive-threshold0.6-alpha_high0.9.db",
        "timid-alpha_max0.3.db",
        "today-D0.35.db",
        "today.db",
    ]
    variant = tomllib.loads(
        (out / "protocols" / "protocol-timid-alpha_max0.5-D0.35.toml").read_text()
    )
    assert variant["confidence"]["D"] == 0.35

    # run again: every store is kept, nothing is simulated twice, same verdict
    code = study_main([*argv[:-5], "--no-progress"])
    printed, err = capsys.readouterr()
    assert code == 0, err
    assert json.loads(printed.strip().splitlines()[-1])["today"] == summary["today"]

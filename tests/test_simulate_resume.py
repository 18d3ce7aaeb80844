"""``python -m study simulate --resume`` continues a killed or failed simulation, and the store
ends up with the data an uninterrupted run with the same seed writes.

The kill is real: a ``python -m study simulate`` process is sent SIGKILL while it is writing a
participant's trials. The full disk is SQLite's own ``SQLITE_FULL`` (a capped ``max_page_count``
on the connection the command opens). Either way, the resumed store is compared with an
uninterrupted run's -- participants, schedule rows, seeds, trials, every sample value, ratings
and event kinds -- leaving out only wall-clock stamps and row ids.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from study.__main__ import main as study_main
from study.simulated import runner
from study.store import Store
from tests.disk_full import cap
from tests.support.simulated_runs import content, progress, shared_reference

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
PARTICIPANTS = 3  # one completed, one being written when killed, one not begun
SEED = 7  # the Dask tests' too: one reference run serves both modules
TRIALS_EACH = 9  # the protocol's one training run and eight task trials


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return shared_reference(tmp_path_factory, participants=PARTICIPANTS, seed=SEED)


@pytest.fixture(scope="module")
def protocol(shared: tuple[Path, Path]) -> Path:
    return shared[0]


@pytest.fixture(scope="module")
def reference(shared: tuple[Path, Path]) -> dict[str, Any]:
    return content(shared[1])


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict[str, Any], str]:
    code = study_main(["simulate", *argv])
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert len(lines) == 1, out
    return code, json.loads(lines[0]), err


def test_killed_simulation_resumes_to_the_uninterrupted_data(
    protocol: Path,
    reference: dict[str, Any],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    db = tmp_path / "sim.db"
    args = [
        "--protocol",
        str(protocol),
        "--db",
        str(db),
        "--participants",
        str(PARTICIPANTS),
        "--seed",
        str(SEED),
        "--no-progress",
    ]
    proc = subprocess.Popen(
        [sys.executable, "-m", "study", "simulate", *args],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        # killed once the second participant's first trial is stored: a few seconds idle; at
        # load 12-16 more than a minute
        deadline = time.monotonic() + 480
        while (
            progress(db)[0] <= TRIALS_EACH and time.monotonic() < deadline and proc.poll() is None
        ):
            time.sleep(0.01)
        assert proc.poll() is None, "the simulation ended before it could be killed"
        assert progress(db)[0] > TRIALS_EACH, (
            "10 trials did not come in 480 s: is the machine idle?"
        )
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    trials, completed = progress(db)
    assert 0 < completed < PARTICIPANTS and trials > TRIALS_EACH

    # re-running without --resume refuses, and says how to continue
    code, summary, err = cli(capsys, *args)
    assert code == 2 and "--resume" in summary["error"] and "continue a killed run" in err

    code, summary, err = cli(capsys, *args, "--resume")
    assert code == 0, err
    assert summary["participants"] == PARTICIPANTS and summary["errors"] == []
    assert len(summary["kept"]) == completed
    assert len(summary["redone"]) == 1  # the one being written when the process died
    assert content(db) == reference


def test_simulation_on_a_full_disk_reports_it_and_resumes(
    protocol: Path,
    reference: dict[str, Any],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    db = tmp_path / "sim.db"
    args = [
        "--protocol",
        str(protocol),
        "--db",
        str(db),
        "--participants",
        str(PARTICIPANTS),
        "--seed",
        str(SEED),
        "--no-progress",
    ]
    real = runner.open_store

    def open_capped(path: Any, protocol: Any, **kw: Any) -> Store:
        store = real(path, protocol, **kw)
        cap(store, extra_pages=1500)
        return store

    with monkeypatch.context() as patch:
        patch.setattr(runner, "open_store", open_capped)  # where simulate() opens the store
        code, summary, err = cli(capsys, *args)
    assert code == 2
    assert "the disk is full" in summary["error"]
    assert 0 < summary["participants"] < PARTICIPANTS  # those finished before the disk filled
    assert "error: " in err and "Traceback" not in err
    with Store.open_readonly(db) as store:
        assert store.integrity_check() == "ok"

    code, summary, err = cli(capsys, *args, "--resume")
    assert code == 0, err
    assert summary["participants"] == PARTICIPANTS and "error" not in summary
    assert content(db) == reference

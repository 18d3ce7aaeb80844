"""``python -m study run``: a whole headless session with the real trial, and its bad inputs."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from app.trial import OUTCOMES
from study.__main__ import main as study_main
from study.cli import run as run_cli
from study.protocol import load_protocol
from study.session import headless, open_store
from study.store import Store

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ROOT / "protocols" / "dragan2013.toml"


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict, str]:
    code = study_main(["run", *argv])
    out, err = capsys.readouterr()
    return code, json.loads(out.strip().splitlines()[-1]), err


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_whole_session_headless(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short_protocol: Path
) -> None:
    db = tmp_path / "study.db"
    args = [
        "--protocol",
        str(short_protocol),
        "--db",
        str(db),
        "--participant",
        "P01",
        "--input",
        "scripted",
        "--seed",
        "1",
        "--demographics",
        '{"age": 27}',
    ]
    code, summary, _ = run(capsys, *args)
    assert code == 0
    assert summary == {
        "participant": "P01",
        "trials_completed": 11,
        "ratings": 31,
        "status": "completed",
    }
    with Store.open_readonly(db) as store:
        assert store.integrity_check() == "ok"
        trials = store.trials()
        assert all(t.status == "completed" for t in trials)
        assert all(t.outcome in OUTCOMES for t in trials)
        assert all(t.ticks == store.sample_count(t.trial_id) > 0 for t in trials)
        assert all(t.duration_s == pytest.approx(t.ticks / 100) for t in trials)
        assert trials[3].goal_names and len(trials[3].goal_positions[0]) == 3
        assert store.demographics("P01") == {"age": 27}
        samples = store.samples(trials[0].trial_id)
        assert samples["alpha"].eq(0).all()  # training runs are unassisted
        assert samples["tick"].tolist() == list(range(trials[0].ticks))
    # the same participant again is refused, the store unchanged
    before = digest(db)
    code, summary, err = run(capsys, *args)
    assert code == 2 and "P01 is already enrolled" in summary["error"]
    assert "error: participant P01 is already enrolled" in err
    code, summary, _ = run(capsys, *args, "--resume")
    assert code == 2 and "already completed" in summary["error"]
    assert digest(db) == before


def test_bad_inputs_name_the_problem(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short_protocol: Path
) -> None:
    db = tmp_path / "study.db"
    base = ["--db", str(db), "--input", "scripted"]
    code, summary, _ = run(
        capsys, *base, "--protocol", str(short_protocol), "--participant", "P07", "--resume"
    )
    assert code == 2 and summary["status"] == "error"
    assert "--resume needs the store the session started in" in summary["error"]
    assert not db.exists()  # a mistyped store path creates nothing
    code, summary, _ = run(
        capsys, *base, "--protocol", str(short_protocol), "--participant", "jane@example.org"
    )
    assert code == 2 and "not a pseudonym" in summary["error"]
    # a store written by one protocol refuses another, untouched
    protocol = load_protocol(short_protocol)
    open_store(db, protocol).close()
    code, summary, _ = run(
        capsys, *base, "--protocol", str(short_protocol), "--participant", "P07", "--resume"
    )
    assert code == 2 and "participant P07 is not enrolled" in summary["error"]
    before = digest(db)
    code, summary, _ = run(capsys, *base, "--protocol", str(PROTOCOL), "--participant", "P01")
    assert code == 2 and "was written by protocol 'dragan2013'" in summary["error"]
    assert digest(db) == before
    junk = tmp_path / "junk.db"
    junk.write_text("not a database at all " * 50)
    code, summary, _ = run(
        capsys, "--db", str(junk), "--protocol", str(PROTOCOL), "--participant", "P01"
    )
    assert code == 2 and "not a SQLite database" in summary["error"]


def test_unexpected_failure_keeps_data_and_says_resume(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    short_protocol: Path,
) -> None:
    def crash_mid_trial(session, **_: object):
        session.start()
        session.agree()
        run = session.start_trial(input_source=headless.scripted_input(session.trial_config(), 1))
        run.tick()
        raise RuntimeError("boom in the control loop")

    monkeypatch.setattr(run_cli, "run_headless", crash_mid_trial)  # where the command calls it
    db = tmp_path / "study.db"
    code, summary, err = run(
        capsys, "--db", str(db), "--protocol", str(short_protocol), "--participant", "P01"
    )
    assert code == 1 and summary["status"] == "error"
    assert summary["error"] == "RuntimeError: boom in the control loop"
    assert "Traceback" in err and "--resume" in err
    with Store.open_readonly(db) as store:
        (trial,) = store.trials(raw=True)
        assert trial.status == "interrupted" and store.sample_count(trial.trial_id) == 1
        assert store.session("P01").status == "running"  # resumable

"""Bad seeds, design rows and store paths are refused before anything is written, with a typed
error (or an argparse usage error) instead of a traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from study.__main__ import main as study_main
from study.protocol import Protocol, load_protocol
from study.schedule import ScheduleError
from study.session import MAX_SEED, InvalidSeedError, Session, SessionError, open_store
from study.store import Store

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL = ROOT / "protocols" / "dragan2013.toml"


@pytest.fixture(scope="module")
def protocol() -> Protocol:
    return load_protocol(PROTOCOL)


def study(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    try:
        code = study_main(list(argv))
    except SystemExit as exc:  # argparse refused the arguments
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def resume(capsys: pytest.CaptureFixture[str], db: Path) -> tuple[int, str, str]:
    """``python -m study run ... --participant P01 --resume`` on the store ``db``."""
    return study(
        capsys,
        "run",
        "--protocol",
        str(PROTOCOL),
        "--db",
        str(db),
        "--participant",
        "P01",
        "--resume",
    )


def participants(db: Path) -> list[str]:
    with Store.open_readonly(db) as store:
        return list(store.frame("participants")["participant"])


@pytest.mark.parametrize("seed", [-1, MAX_SEED + 1, 1.5, True, "3"])
def test_enrol_refuses_a_bad_seed_before_writing(
    tmp_path: Path, protocol: Protocol, seed: object
) -> None:
    db = tmp_path / "study.db"
    with (
        open_store(db, protocol) as store,
        pytest.raises(InvalidSeedError, match=r"seed must be a whole number from 0"),
    ):
        Session.enrol(store, protocol, "P01", seed=seed)
    assert participants(db) == []


def test_enrol_refuses_a_negative_schedule_row_before_writing(
    tmp_path: Path, protocol: Protocol
) -> None:
    db = tmp_path / "study.db"
    with (
        open_store(db, protocol) as store,
        pytest.raises(ScheduleError, match="design rows are integers >= 0, got -1"),
    ):
        Session.enrol(store, protocol, "P01", seed=1, schedule_row=-1)
    assert participants(db) == []


def test_enrol_accepts_the_largest_seed(tmp_path: Path, protocol: Protocol) -> None:
    with open_store(tmp_path / "study.db", protocol) as store:
        session = Session.enrol(store, protocol, "P01", seed=MAX_SEED)
        try:
            assert session.seed == MAX_SEED
        finally:
            session.close()


def test_resume_of_a_session_stored_with_a_bad_seed_is_refused(
    tmp_path: Path, protocol: Protocol, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "study.db"
    with open_store(db, protocol) as store, store.transaction() as tx:
        tx.enrol("P01", schedule_row=0, assignments=[], seed=-1)  # as older versions allowed
    with open_store(db, protocol) as store:
        with pytest.raises(InvalidSeedError, match="enrolled with seed -1") as info:
            Session.reopen(store, protocol, "P01")
        assert isinstance(info.value, SessionError)
    code, out, err = resume(capsys, db)
    assert code == 2 and "Traceback" not in err
    assert "enrolled with seed -1" in json.loads(out.strip().splitlines()[-1])["error"]


@pytest.mark.parametrize(
    ("command", "flag"),
    [
        ("run", "--seed"),
        ("run", "--schedule-row"),
        ("simulate", "--seed"),
        ("simulate", "--first"),
        ("simulate", "--participants"),
        ("simulate", "--workers"),
    ],
)
def test_negative_numbers_are_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, flag: str
) -> None:
    db = tmp_path / "study.db"
    argv = [command, "--protocol", str(PROTOCOL), "--db", str(db)]
    if command == "run":
        argv += ["--participant", "P01"]
    else:
        argv += ["--no-progress"]
    code, _, err = study(capsys, *argv, flag, "-1")
    assert code == 2
    assert f"argument {flag}: must be" in err and "got -1" in err and "Traceback" not in err
    assert not db.exists()


def test_resume_with_a_missing_store_creates_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "typo.db"
    code, out, err = resume(capsys, db)
    assert code == 2 and "Traceback" not in err
    message = f"no store at {db}; --resume needs the store the session started in"
    assert message in err
    assert json.loads(out.strip().splitlines()[-1])["error"] == message
    assert list(tmp_path.iterdir()) == []

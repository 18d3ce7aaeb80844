"""Protocol and population files that are not UTF-8 fail with a typed error that names the file
and the byte offset, never a UnicodeDecodeError traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from study.__main__ import main as study_main
from study.protocol import ProtocolError, load_protocol
from study.simulated import DEFAULT_POPULATION_PATH, PopulationError, load_population

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"


def latin1_copy(source: Path, target: Path) -> int:
    """``source`` with a Latin-1 comment ("café") appended; returns the offset of the bad byte."""
    data = source.read_bytes() + "\n# café\n".encode("latin-1")
    target.write_bytes(data)
    return data.index(b"\xe9")


def test_a_latin1_protocol_is_a_protocol_error(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    offset = latin1_copy(PAPER, path)
    with pytest.raises(ProtocolError) as info:
        load_protocol(path)
    assert str(info.value) == (
        f"{path}: not UTF-8 text (byte offset {offset}); re-save it as UTF-8"
    )
    assert info.value.__cause__ is None and info.value.__suppress_context__


def test_a_latin1_population_is_a_population_error(tmp_path: Path) -> None:
    path = tmp_path / "population.toml"
    offset = latin1_copy(DEFAULT_POPULATION_PATH, path)
    with pytest.raises(PopulationError) as info:
        load_population(path)
    assert str(info.value) == (
        f"{path}: not UTF-8 text (byte offset {offset}); re-save it as UTF-8"
    )


def test_run_with_a_latin1_protocol_exits_2_without_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "latin1.toml"
    latin1_copy(PAPER, path)
    db = tmp_path / "study.db"
    code = study_main(
        ["run", "--protocol", str(path), "--db", str(db), "--participant", "P01"],
    )
    out, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in err and "not UTF-8 text" in err
    assert "re-save it as UTF-8" in json.loads(out.strip().splitlines()[-1])["error"]
    assert not db.exists()

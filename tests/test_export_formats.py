"""Exporting again into a folder: no table files of an earlier export stay behind, a failed
export leaves the folder as it was, and analysis reads what metadata.json says was written."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from analysis.errors import SourceError
from analysis.load import from_export
from study.__main__ import main as study_main
from study.protocol import load_protocol
from study.session import open_store
from tests.support.exports import PAPER, build_store

TABLES = ("trials", "samples", "ratings", "answers", "participants", "events")


@pytest.fixture(scope="module")
def stores(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A store with 7 trials (keeps no protocol text) and an empty one that keeps it."""
    protocol = load_protocol(PAPER)
    d = tmp_path_factory.mktemp("stores")
    full = d / "full.sqlite"
    build_store(full, protocol)
    empty = d / "empty.sqlite"
    open_store(empty, protocol).close()
    return full, empty


def export(capsys: pytest.CaptureFixture[str], db: Path, out: Path, *extra: str) -> dict:
    code = study_main(["export", "--db", str(db), "--out", str(out), *extra])
    stdout, stderr = capsys.readouterr()
    assert code == 0, stderr
    return json.loads(stdout.strip().splitlines()[-1])


def test_csv_export_over_a_full_export_leaves_no_parquet(
    stores: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    full, empty = stores
    out = tmp_path / "export"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "figure.parquet").write_bytes(b"not an export file")
    export(capsys, full, out)
    assert (out / "trials.parquet").is_file() and not (out / "protocol.toml").exists()
    assert len(from_export(out).trials) == 7

    summary = export(capsys, empty, out, "--format", "csv")
    assert summary["rows"]["trials"] == 0
    assert not any((out / f"{name}.parquet").exists() for name in TABLES)
    assert all((out / f"{name}.csv").is_file() for name in TABLES)
    assert (out / "protocol.toml").is_file()  # the empty store keeps its protocol text
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["formats"] == ["csv"] and meta["rows"]["trials"] == 0
    assert len(from_export(out).trials) == 0  # not the 7 trials of the earlier export

    export(capsys, full, out, "--format", "parquet")
    assert not any((out / f"{name}.csv").exists() for name in TABLES)
    assert not (out / "protocol.toml").exists()  # the earlier store's protocol is not this one's
    assert len(from_export(out).trials) == 7
    # files an export does not write are left alone, and no staging folder is left behind
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "figure.parquet").read_bytes() == b"not an export file"
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []


def test_a_failed_export_leaves_the_folder_as_it_was(
    stores: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    full, empty = stores
    out = tmp_path / "export"
    export(capsys, full, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def disk_full(self: pd.DataFrame, *args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pd.DataFrame, "to_parquet", disk_full)
    code = study_main(["export", "--db", str(empty), "--out", str(out)])
    _, stderr = capsys.readouterr()
    assert code == 2 and "No space left" in stderr and "Traceback" not in stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert len(from_export(out).trials) == 7


def test_from_export_reads_the_formats_metadata_lists(
    stores: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    full, empty = stores
    old = tmp_path / "old"
    export(capsys, full, old, "--format", "parquet")
    out = tmp_path / "export"
    export(capsys, empty, out, "--format", "csv")
    # a Parquet file copied in by hand is not part of this export and is not read
    (out / "trials.parquet").write_bytes((old / "trials.parquet").read_bytes())
    assert len(from_export(out).trials) == 0


def test_from_export_refuses_tables_whose_rows_disagree_with_metadata(
    stores: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    full, _ = stores
    out = tmp_path / "export"
    export(capsys, full, out)
    trials = pd.read_parquet(out / "trials.parquet")
    trials.iloc[:3].to_parquet(out / "trials.parquet", index=False)
    with pytest.raises(SourceError, match=r"trials\.parquet has 3 rows.*says the export wrote 7"):
        from_export(out)
    (out / "trials.parquet").unlink()  # now trials.csv (7 rows) is read
    assert len(from_export(out).trials) == 7
    (out / "samples.csv").unlink()
    (out / "samples.parquet").unlink()
    with pytest.raises(SourceError, match=r"no samples table.*9 rows"):
        from_export(out)


def test_from_export_refuses_a_broken_metadata_file(tmp_path: Path) -> None:
    pd.DataFrame({"participant": []}).to_csv(tmp_path / "trials.csv", index=False)
    (tmp_path / "metadata.json").write_text("{not json")
    with pytest.raises(SourceError, match=r"metadata\.json"):
        from_export(tmp_path)
    (tmp_path / "metadata.json").write_text(json.dumps({"formats": ["xlsx"]}))
    with pytest.raises(SourceError, match="xlsx"):
        from_export(tmp_path)

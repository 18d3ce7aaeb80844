"""The store keeps its protocol's text: export rebuilds the exact protocol after the file changed,
another protocol is refused with both hashes and what changed, schema-1 stores still open."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest

from study.__main__ import main as study_main
from study.export import export_metadata, resolve_protocol, tidy_tables
from study.protocol import StoredProtocolError, load_protocol, protocol_from_store
from study.session import Session, open_store
from study.store import SAMPLE_COLUMNS, SCHEMA_VERSION, ProtocolMismatchError, Store
from tests.support.cli import run_main

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "protocols" / "dragan2013.toml"
LIKERT = ["helpful", "matched", "teammate", "preference", "preference_aggressive"]


@pytest.fixture()
def study(tmp_path: Path) -> tuple[Path, Path, str]:
    """A store made by ``open_store`` for a copy of the paper's protocol (dir/dragan2013.toml)."""
    protocols = tmp_path / "protocols"
    protocols.mkdir()
    path = protocols / "dragan2013.toml"
    text = PAPER.read_text()
    path.write_text(text)
    db = tmp_path / "study.db"
    open_store(db, load_protocol(path)).close()
    return db, path, text


def edit(path: Path) -> None:
    """Change the protocol file as a researcher might between two pilot sessions."""
    text = path.read_text()
    assert text.count("threshold = 0.4,") == 1
    path.write_text(text.replace("threshold = 0.4,", "threshold = 0.3,"))


def test_store_keeps_the_protocol_text_and_rebuilds_it(study: tuple[Path, Path, str]) -> None:
    db, path, text = study
    original = load_protocol(path)
    with Store.open_readonly(db) as store:
        assert store.meta.version == SCHEMA_VERSION
        assert store.protocol_text() == text  # comments and layout kept
        rebuilt = protocol_from_store(store)
    assert rebuilt.content_hash == original.content_hash
    assert rebuilt.mode("aggressive").arbitration == original.mode("aggressive").arbitration
    assert [i.id for i in rebuilt.questionnaire.after_run] == ["helpful", "matched", "teammate"]


def test_export_uses_the_stored_protocol_after_the_file_changed(
    study: tuple[Path, Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db, path, text = study
    edit(path)
    with Store.open_readonly(db) as store:
        protocol, source = resolve_protocol(store, search=[path.parent])
        assert source == "store" and protocol is not None
        assert protocol.mode("aggressive").arbitration["threshold"] == 0.4  # the one that ran
        tables = tidy_tables(store, search=[path.parent])
        assert export_metadata(store, tables, protocol=protocol)["protocol_stored"] is True
    # an empty store: only the protocol can name the item columns (nothing to infer them from)
    assert set(LIKERT) <= set(tables["trials"].columns)
    out = tmp_path / "out"
    # the export command line's main in this process (what it writes and says is checked)
    proc = run_main(study_main, ["export", "--db", str(db), "--out", str(out)], capsys)
    assert proc.returncode == 0, proc.stderr
    assert "note:" not in proc.stderr
    assert (out / "protocol.toml").read_text() == text
    assert json.loads((out / "metadata.json").read_text())["protocol_stored"] is True


def test_edited_protocol_is_refused_with_both_hashes_and_what_changed(
    study: tuple[Path, Path, str],
) -> None:
    db, path, _ = study
    original = load_protocol(path)
    edit(path)
    edited = load_protocol(path)
    before = db.read_bytes()
    with pytest.raises(ProtocolMismatchError) as err:
        open_store(db, edited)
    message = str(err.value)
    assert original.content_hash in message and edited.content_hash in message
    assert "changed: modes.aggressive" in message
    assert "new --db" in message and "protocol.toml" in message
    assert db.read_bytes() == before
    with open_store(db, original) as store:  # the original still opens
        with pytest.raises(ProtocolMismatchError, match=r"changed: modes\.aggressive"):
            Session.enrol(store, edited, "P01")
        assert store.participants() == []


def test_tampered_stored_text_is_reported(study: tuple[Path, Path, str]) -> None:
    db, _, text = study
    conn = sqlite3.connect(db)
    conn.execute("UPDATE protocols SET text = ?", (text.replace("0.4,", "0.35,", 1),))
    conn.commit()
    conn.close()
    with (
        Store.open_readonly(db) as store,
        pytest.raises(StoredProtocolError, match="altered outside the platform"),
    ):
        protocol_from_store(store)


def make_schema_1(db: Path) -> None:
    """Turn a store into what the schema-1 platform wrote (no protocols or answers table)."""
    conn = sqlite3.connect(db)
    conn.execute("DROP TABLE protocols")
    conn.execute("DROP TABLE answers")  # added by schema 3
    conn.execute("ALTER TABLE samples DROP COLUMN motion_agreement")  # columns added after schema 1
    conn.execute("ALTER TABLE samples DROP COLUMN rationality")
    conn.execute("UPDATE schema_version SET version = 1")
    conn.commit()
    conn.close()


def test_schema_1_store_reads_then_upgrades_when_opened_for_writing(
    study: tuple[Path, Path, str],
) -> None:
    db, path, text = study
    make_schema_1(db)
    with Store.open_readonly(db) as store:
        assert store.meta.version == 1 and store.protocol_text() is None
        assert store.frame("protocols").empty
        samples = store.samples()  # the columns schema 1 lacks come back empty
        assert list(samples.columns) == list(SAMPLE_COLUMNS)
        assert samples["rationality"].isna().all()
        with pytest.raises(StoredProtocolError, match="pass the protocol file"):
            protocol_from_store(store)
        protocol, source = resolve_protocol(store, search=[path.parent])
        assert protocol is not None and source == f"file {path}"  # the unedited file matches
        protocol, source = resolve_protocol(store, search=[])
        assert protocol is None and "inferred" in source
    with open_store(db, load_protocol(path)) as store:
        assert store.meta.version == SCHEMA_VERSION and store.protocol_text() == text
    with Store.open_readonly(db) as store:
        assert store.meta.version == SCHEMA_VERSION
        assert protocol_from_store(store).content_hash == load_protocol(path).content_hash

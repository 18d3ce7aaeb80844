"""The report describes the protocol the data were collected with: the text the store (or the
export folder) keeps wins over a protocol file edited since, and a file is the fallback."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from analysis.load import from_frames
from analysis.protocol_info import load_protocol_info
from analysis.report import write_report
from analysis.synthetic import synthetic_tables
from study.protocol import load_protocol
from study.session import open_store


@pytest.fixture
def edited_after_the_study(tmp_path: Path, protocol_path: Path) -> tuple[Path, Path, dict]:
    """A store made with a copy of the paper's protocol, then the copy's timid mode retuned."""
    path = tmp_path / "study.toml"
    path.write_text(protocol_path.read_text())
    protocol = load_protocol(path)
    open_store(tmp_path / "study.db", protocol).close()
    ran_with = {m.name: dict(m.arbitration) for m in protocol.modes}
    text, n = re.subn(
        r"(?m)^(arbitration = \{ kind = \"timid\", alpha_max = )[0-9.]+",
        r"\g<1>0.25",
        path.read_text(),
    )
    assert n == 1 and ran_with["timid"]["alpha_max"] != 0.25
    path.write_text(text)
    return tmp_path / "study.db", path, ran_with


def test_stored_protocol_wins_over_a_file_edited_afterwards(edited_after_the_study) -> None:
    db, path, ran_with = edited_after_the_study
    from study.store import Store

    with Store.open_readonly(db) as store:
        stored_hash = store.meta.protocol_hash
    from_file = load_protocol_info(path)
    assert from_file.content_hash != stored_hash  # the file really moved on
    assert from_file.arbitrations["timid"]["alpha_max"] == 0.25
    info = load_protocol_info(path, stored=db)
    assert info.content_hash == stored_hash
    assert info.arbitrations == ran_with  # Fig. 7's curves are the ones the study ran with
    assert info.path.endswith("(stored protocol)")
    assert any(str(path) in n and "not used" in n for n in info.notes)


def test_report_hash_and_figure_come_from_the_store(edited_after_the_study, tmp_path: Path) -> None:
    db, path, _ = edited_after_the_study
    trials = synthetic_tables(2, seed=1, with_samples=False)["trials"]
    tables = from_frames(trials[trials.phase == "training"], source=str(db))
    files = write_report(tables, tmp_path / "report", protocol_path=path)
    doc = json.loads(files.results_json.read_text())
    assert doc["protocol"]["content_hash"] == load_protocol_info(path, stored=db).content_hash
    assert doc["protocol"]["content_hash"] != load_protocol_info(path).content_hash
    assert doc["protocol"]["path"].endswith("(stored protocol)")


def test_export_folder_protocol_wins_and_plain_sources_fall_back_to_the_file(
    tmp_path: Path, protocol_path: Path, edited_after_the_study
) -> None:
    _, edited, ran_with = edited_after_the_study
    export = tmp_path / "export"
    export.mkdir()
    assert load_protocol_info(edited, stored=export).arbitrations["timid"]["alpha_max"] == 0.25
    (export / "protocol.toml").write_text(protocol_path.read_text())
    info = load_protocol_info(edited, stored=export)
    assert info.arbitrations == ran_with and info.path == str(export / "protocol.toml")
    assert load_protocol_info(edited, stored="in-memory tables").path == str(edited)

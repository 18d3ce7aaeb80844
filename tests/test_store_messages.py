"""Store errors name no command-line flag: ``study``/``analysis`` call it --db, ``app render``
calls it --store."""

from __future__ import annotations

from pathlib import Path

import pytest

from study.store import Store, StoreError


def test_a_missing_store_names_no_flag(tmp_path: Path) -> None:
    path = tmp_path / "absent.db"
    with pytest.raises(StoreError) as info:
        Store.open_readonly(path)
    message = str(info.value)
    assert message.startswith(f"no store at {path}")
    assert "check the store path" in message
    assert "--db" not in message and "--store" not in message
    assert not path.exists()

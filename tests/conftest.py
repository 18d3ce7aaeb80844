"""Shared test configuration: headless MuJoCo rendering and the repository root."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.protocol_copies import short_protocol as _short_protocol

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def protocol_path() -> Path:
    return ROOT / "protocols" / "dragan2013.toml"


@pytest.fixture(scope="session")
def short_protocol(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's protocol with 20 s trials, so runs that cannot finish end sooner."""
    return _short_protocol(tmp_path_factory.mktemp("protocol"))

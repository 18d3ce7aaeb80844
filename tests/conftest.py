"""Shared test configuration: headless MuJoCo rendering, the repository root, and how the
suite is shared among pytest-xdist workers (``-n auto --dist loadgroup``, pyproject.toml)."""

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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under pytest-xdist each test module runs whole on one worker (its module-scoped fixtures,
    such as a simulated reference store, are built once), and the browser tests run one after
    another on one worker: two software-WebGL Chromiums at once on two cores would each draw
    at half speed, and their tests steer by what they see."""
    for item in items:
        if item.get_closest_marker("xdist_group") is not None:
            continue
        group = "browser" if item.get_closest_marker("browser") else item.module.__name__
        item.add_marker(pytest.mark.xdist_group(group))

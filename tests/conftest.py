"""Shared test configuration: headless MuJoCo rendering, the repository root, and how the
suite is shared among pytest-xdist workers (``-n auto --dist loadgroup``, pyproject.toml)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

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


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups into the test ids
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under pytest-xdist each test module runs whole on one worker (its module-scoped fixtures,
    such as a simulated reference store, are built once), and the browser tests run one after
    another on one worker: two software-WebGL Chromiums at once on two cores would each draw
    at half speed, and their tests steer by what they see."""
    for item in items:
        if item.get_closest_marker("xdist_group") is not None:
            continue
        module = item.nodeid.split("::", 1)[0]
        group = "browser" if item.get_closest_marker("browser") else module
        item.add_marker(pytest.mark.xdist_group(group))


BROWSER_TESTS = "tests/browser/"
LONGEST_FIRST = (
    "browser",
    "tests/test_simulate_resume.py",
    "tests/test_simulate_dask.py",
    "tests/test_examples.py",
    "tests/test_sweep.py",
    "tests/test_simulate_workers.py",
    "tests/test_adaptive_protocol.py",
)
"""The groups that take longest (``--durations``, 2 cores, December 2026), handed out first:
the browser lane alone is about half the suite's time, so it must not wait behind short
modules (xdist otherwise starts the groups with the most tests first). Order only: a group
missing here runs after these, in xdist's order."""


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """``--dist loadgroup`` that groups as the hook above says even where pytest-xdist cannot
    read the groups: xdist 3.8 writes each test's group into ``item._nodeid``, which pytest 9
    no longer reads (a test's id comes from ``item._id``), so every test was scheduled alone
    -- a module's tests on both workers, each building its module fixtures (a simulated
    reference store twice), and browser tests on both workers at once. The group is read from
    the test's id: xdist's ``@group`` suffix where it is there, else ``browser`` for every test
    under tests/browser/ (the only browser tests) and the module's path for the others."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class ByModule(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            if nodeid.rfind("@") > nodeid.rfind("]"):
                return nodeid.rsplit("@", 1)[-1]
            path = nodeid.split("::", 1)[0]
            return "browser" if path.startswith(BROWSER_TESTS) else path

        def _assign_work_unit(self, node: Any) -> None:
            for group in reversed(LONGEST_FIRST):
                if group in self.workqueue:
                    self.workqueue.move_to_end(group, last=False)
            super()._assign_work_unit(node)

    return ByModule(config, log)

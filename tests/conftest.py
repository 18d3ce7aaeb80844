"""Shared test configuration: headless MuJoCo rendering, the repository root, and how the
suite is shared among pytest-xdist workers (``-n auto --dist loadgroup``, pyproject.toml)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

from tests.browser import harness as _harness
from tests.protocol_copies import short_protocol as _short_protocol

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

ROOT = Path(__file__).resolve().parents[1]

# A worker starts hundreds of study servers one after another; each start's full collection
# before freezing the heap walked the whole worker (~180 ms at 420,000 objects, about 45 CPU s a
# run). The tests about the port under attack turn it back on: it is what keeps their control
# loop on time (``study.server.realtime``).
_harness.SERVER_DEFAULTS["freeze_heap"] = False


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


BROWSER_TESTS = "tests/browser/"
BROWSER_LANES = {
    "tests/browser/test_depth_and_limits.py": "browser-1",
    "tests/browser/test_whole_session_by_hand.py": "browser-1",
    "tests/browser/test_open_link.py": "browser-1",
    "tests/browser/test_participant_page.py": "browser-1",
    "tests/browser/test_missed_grasp.py": "browser-1",
    "tests/browser/test_key_state.py": "browser-1",
    "tests/browser/test_intent_display.py": "browser-1",
    "tests/browser/test_relative_handle.py": "browser-3",
    "tests/browser/test_questionnaire.py": "browser-3",
    "tests/browser/test_tls_proxy.py": "browser-3",
    "tests/browser/test_join_and_console.py": "browser-3",
    "tests/browser/test_handle_pace.py": "browser-3",
}
"""The browser tests' lanes, each run by one worker one test after another; a module not
listed runs in ``browser-2`` (blinding, participant flow, console day, keys and pause).
``browser-3`` holds five short, light modules (about 50 s together), handed out after the long
non-browser modules: with four workers the lanes set the run's end (2026-12-04: the second
lane ended at 336 s, 30 s after the three other workers, the first at 284 s), so intent moved
to the first lane and five short modules out of both; a third page is open beside the lanes
for about 50 s.
Balanced by ``--durations`` of both lanes run together (`-n 2`, 2 cores, other jobs at load
5-15, December 2026): 422 and 431 s. Chromium's CPU is most of theirs and ``/usr/bin/time``
misses it (its renderer and GPU processes are not waited for): sampled from /proc, the 22
tests used 591 CPU s in that run (Chromium 456, the two workers 110, Playwright's node 18), not
the 197 once measured. Chromium draws on demand, about 0.1 CPU s a second for a still page,
but while the arm moves it draws as fast as the CPU lets it, near a core a page at any window
size (1366 x 768: 9 frames/s, 800 x 600: 14, both 0.85 CPU s a second); the tests' pages now
draw at most 10 frames a second (``tests.browser.harness.FRAME_CAP_FPS``: both lanes 412 -> 364
CPU s in a paired run, twelfth session). A third lane (tried: 409-470 s each beside jobs at load
17-21, 675 CPU s; again with the cap and four workers, beside a helper's attack runs: 7 min 53 s
against 7 min 43 s for two lanes and three workers, and two starvation failures) adds a third
such page against the other workers for the whole run: the CPU does not allow it; the short
third group does it for 50 s (5 min 25 s, cores 97 % busy, against 5 min 51 s without it)."""


def _group(nodeid: str) -> str:
    """The xdist group of a test: its browser lane, or its module (module fixtures, such as a
    simulated reference store, are built once)."""
    path = nodeid.split("::", 1)[0]
    if path.startswith(BROWSER_TESTS):
        return BROWSER_LANES.get(path, "browser-2")
    return path


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups into the test ids
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under pytest-xdist each test module runs whole on one worker, and the browser tests in
    two lanes (:data:`BROWSER_LANES`)."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(_group(item.nodeid)))


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: two workers a core, at most four (``--maxprocesses``). Three from 2026-12-03,
    when four starved the browser lanes and the port tests in 2 of 3 full runs; four again from
    2026-12-04, once those tests were hardened and the long modules handed out longest first
    (:data:`LONGEST_FIRST`): with setup's compiled kernels, from a clean clone, 2 cores
    (``benchmarks/suite.py``): 5 min 39 s on four workers, cores 93 % busy, against 6 min 21 s
    on three, 84 % busy: a fourth worker is work for the cores while three wait. Many tests
    wait -- on paced control loops, attack scripts' seconds, subprocesses -- so twice as many
    workers as cores keep the cores busier (2 -> 4 workers: 12:41 -> 11:31 on 2 cores). The
    suite as a whole is nearly CPU-bound on 2 cores: about 640-680 CPU s, Chromium's drawing
    about 265 of them (:data:`BROWSER_LANES`)."""
    return 2 * (os.cpu_count() or 1)


LONGEST_FIRST = (
    "browser-1",
    "browser-2",
    "tests/test_simulate_dask.py",
    "tests/test_port_attacks.py",
    "tests/test_port_hostile_clients.py",
    "browser-3",
    "tests/test_analysis_report.py",
    "tests/test_sweep.py",
    "tests/test_factor_protocols_simulated.py",
    "tests/test_examples.py",
    "tests/test_simulate_resume.py",
    "tests/test_simulate_workers.py",
    "tests/test_crash.py",
    "tests/test_adaptive_protocol.py",
    "tests/test_server_layout.py",
    "tests/test_cli_arguments.py",
    "tests/test_finished_sessions.py",
)
"""The groups that take longest, longest first (wall time in a full run on four workers, 2
cores, 2026-12-04: Dask 116 s, the port attacks 107, hostile clients 77, the analysis report
30, the sweep 26, the factor protocols 22, examples 22, resume 21, workers 20, the kill -9
test 18, adaptive 17, server layout 16, CLI arguments 14, finished sessions 12; the third
browser group, about 50 s, after the port tests), handed out first: the browser lanes must
not wait behind short modules, and a long module must not start last (xdist otherwise starts
the groups with the most tests first: the kill -9 test's 18 s of waiting on its subprocess
began after both lanes had ended and was the run's last 15 s). Order only: a group missing
here runs after these, in xdist's order."""


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """``--dist loadgroup`` that groups as the hook above says even where pytest-xdist cannot
    read the groups: xdist 3.8 writes each test's group into ``item._nodeid``, which pytest 9
    no longer reads (a test's id comes from ``item._id``), so every test was scheduled alone
    -- a module's tests on both workers, each building its module fixtures (a simulated
    reference store twice), and browser tests on every worker at once. The group is read from
    the test's id: xdist's ``@group`` suffix where it is there, else :func:`_group`'s."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class ByModule(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            if nodeid.rfind("@") > nodeid.rfind("]"):
                return nodeid.rsplit("@", 1)[-1]
            return _group(nodeid)

        def _assign_work_unit(self, node: Any) -> None:
            for group in reversed(LONGEST_FIRST):
                if group in self.workqueue:
                    self.workqueue.move_to_end(group, last=False)
            super()._assign_work_unit(node)

    return ByModule(config, log)

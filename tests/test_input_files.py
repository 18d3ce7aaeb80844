"""Every file a command reads is looked at before it is read, and every scene is checked before
a session starts (issue 22).

An attack pass fed the readers ``/dev/zero`` (MemoryError after 2-4 GB), a FIFO (a hang) and a
50 MB protocol (accepted), and a protocol whose ``start_q`` lay outside the joint limits
passed validation and ended ``run`` with a traceback after the practice runs. Each is now a
typed error naming the file, at once, before anything is written.
"""

from __future__ import annotations

import os
import re
import threading
from pathlib import Path

import pytest

from app.files import InputFileError, check_input_file, read_text_file
from app.robot.arm import load_arm
from app.robot.scene_spec import JOINT_LIMITS
from study.__main__ import main as study_main
from study.protocol import ProtocolError, load_protocol
from study.protocol.preflight import check_scenes
from study.simulated import PopulationError
from study.simulated.population import load_population
from tests.protocol_copies import PAPER_PROTOCOL
from tests.support.cli import run_main


@pytest.fixture
def fifo(tmp_path: Path) -> Path:
    path = tmp_path / "pipe.toml"
    os.mkfifo(path)
    return path


def within(seconds: float, call: object) -> BaseException | None:
    """Run ``call()`` in a thread; fail if it has not returned after ``seconds`` (a hang)."""
    box: dict[str, BaseException | None] = {"error": None}

    def run() -> None:
        try:
            call()  # type: ignore[operator]
        except BaseException as exc:
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), "the reader hung"
    return box["error"]


def test_the_readers_refuse_devices_pipes_folders_and_huge_files(
    tmp_path: Path, fifo: Path
) -> None:
    big = tmp_path / "big.toml"
    with big.open("wb") as f:  # 50 MB, sparse
        f.truncate(50 * 2**20)
    cases = {
        Path("/dev/zero"): "is a device, not a file",
        fifo: "is a pipe (FIFO), not a file",
        tmp_path: "is a folder, not a file",
        big: "is 50.0 MB, more than the 1.0 MB",
        tmp_path / "absent.toml": "does not exist",
    }
    for path, problem in cases.items():
        error = within(5.0, lambda p=path: read_text_file(p, max_bytes=2**20, what="protocol file"))
        assert isinstance(error, InputFileError) and problem in str(error), (path, error)
        error = within(5.0, lambda p=path: check_input_file(p, max_bytes=2**20))
        assert isinstance(error, InputFileError) and problem in str(error), (path, error)


def test_protocol_and_population_files_are_bounded(tmp_path: Path, fifo: Path) -> None:
    for path in (Path("/dev/zero"), fifo):
        error = within(5.0, lambda p=path: load_protocol(p))
        assert isinstance(error, ProtocolError) and "not a file" in str(error)
        error = within(5.0, lambda p=path: load_population(p))
        assert isinstance(error, PopulationError) and "not a file" in str(error)
    padded = tmp_path / "padded.toml"
    padded.write_text(PAPER_PROTOCOL.read_text(encoding="utf-8") + "#" * 2**21 + "\n")
    with pytest.raises(ProtocolError, match=r"more than the 1\.0 MB"):
        load_protocol(padded)


def edited(tmp_path: Path, pattern: str, replacement: str) -> Path:
    """A copy of the paper's protocol with the first match of ``pattern`` replaced."""
    text, n = re.subn(pattern, replacement, PAPER_PROTOCOL.read_text(encoding="utf-8"), count=1)
    assert n == 1, pattern
    path = tmp_path / "edited.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_start_pose_outside_the_joint_limits_fails_when_the_protocol_loads(
    tmp_path: Path,
) -> None:
    path = edited(
        tmp_path, r"start_q = \[[^\]]*\]", "start_q = [0.0, -0.339, 0.0, -0.01, 0.0, 2.311, 0.785]"
    )
    with pytest.raises(ProtocolError) as info:
        load_protocol(path)
    assert info.value.key == "scenes.easy.start_q"
    assert "joint 4 = -0.0100 not in [-3.0718, -0.0698]" in info.value.problem


def test_the_joint_limits_the_loader_checks_are_the_arm_models() -> None:
    arm = load_arm()
    limits = tuple(zip(arm.lower.tolist(), arm.upper.tolist(), strict=True))
    assert limits == JOINT_LIMITS


@pytest.mark.parametrize(
    ("pattern", "replacement", "problem"),
    [
        (
            r"position = \[0.64, 0.06, 0.035\]",
            'position = [0.64, 0.06, 0.035]\nyaw = "abc"',
            "yaw: expected a finite number",
        ),
        (
            r"position = \[0.64, 0.06, 0.035\]",
            "position = [0.64, 0.06, 0.035]\nmass = 1e300",
            "mass: 1e+300 outside",
        ),
        (
            r"rgba = \[0.9, 0.55, 0.15, 1.0\]",
            "rgba = [2.0, 0.0, 0.0, 1.0]",
            "rgba[0]: 2.0 is beyond 1",
        ),
        (r"position = \[0.64, 0.06, 0.035\]", "position = [0.56, -0.06, 0.035]", "overlap"),
        (r"position = \[0.64, 0.06, 0.035\]", "position = [0.64, 5.0, 0.035]", "is beyond 2"),
    ],
)
def test_scene_values_are_bounded_and_objects_on_the_table_and_apart(
    tmp_path: Path, pattern: str, replacement: str, problem: str
) -> None:
    with pytest.raises(ProtocolError, match=re.escape(problem)):
        load_protocol(edited(tmp_path, pattern, replacement))


def test_an_object_out_of_reach_is_found_before_a_session_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IK needs the arm: the commands that start sessions build every scene first."""
    path = edited(tmp_path, r"position = \[0.64, 0.06, 0.035\]", "position = [0.9, 0.06, 0.035]")
    protocol = load_protocol(path)  # the layout alone is fine
    with pytest.raises(ProtocolError) as info:
        check_scenes(protocol)
    assert info.value.key == "scenes.easy" and "cannot be grasped" in info.value.problem
    db = tmp_path / "study.db"
    # the run command line's main in this process: refused before a store is opened
    argv = ["run", "--protocol", str(path), "--db", str(db), "--participant", "P01"]
    proc = run_main(study_main, argv, capsys)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "scenes.easy" in proc.stderr and not db.exists()  # nothing written

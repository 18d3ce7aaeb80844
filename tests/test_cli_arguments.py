"""Command-line values that would break a run later are refused at the command line, by flag.

A rate of 0 froze the participant's scene at its first frame, ``--port 99999`` ended in a
traceback, and a protocol with 5,000 nested arrays in a ``RecursionError``; each now ends in
argparse's usage error (exit code 2, no traceback) or a typed ``ProtocolError``. So do the
cases an attack pass found (issue 22): every flag has a range, every path a kind, and every
error is one line.
"""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import types
from pathlib import Path

import pytest

from study.cli import serve
from study.cli.arguments import non_negative_float, port, rate_hz
from study.cli.dispatch import OneLineParser, dispatch
from study.protocol import ProtocolSyntaxError, load_protocol, parse_protocol
from study.protocol.loader import MAX_NESTING, nesting_depth

ROOT = Path(__file__).resolve().parents[1]
STUDY = (sys.executable, "-m", "study")


def serve_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m study serve")
    serve.add_arguments(parser)
    return parser


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--render-hz", "0"], "argument --render-hz: must be a rate above 0 and at most 60"),
        (["--render-hz", "-5"], "argument --render-hz: must be a rate above 0"),
        (["--render-hz", "nan"], "argument --render-hz: must be a rate above 0"),
        (["--render-hz", "inf"], "argument --render-hz: must be a rate above 0"),
        (["--render-hz", "61"], "at most 60 per second, got 61"),
        (["--render-hz", "fast"], "argument --render-hz: must be a number, got 'fast'"),
        (["--port", "99999"], "argument --port: must be a TCP port from 1 to 65535"),
        (["--port", "-1"], "argument --port: must be a TCP port"),
        (["--port", "80.5"], "argument --port: must be a port number, got '80.5'"),
        (["--experimenter-port", "65536"], "argument --experimenter-port: must be a TCP port"),
    ],
)
def test_serve_refuses_bad_rates_and_ports(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_:
        serve_parser().parse_args(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


def test_serve_accepts_the_edges() -> None:
    args = serve_parser().parse_args(
        ["--render-hz", "60", "--port", "0", "--experimenter-port", "65535"]
    )
    assert (args.render_hz, args.port, args.experimenter_port) == (60.0, 0, 65535)
    assert serve_parser().parse_args(["--render-hz", "0.5"]).render_hz == 0.5


def test_serve_refuses_one_port_for_both_views(tmp_path: Path) -> None:
    """Checked before anything is opened: no store file appears."""
    proc = subprocess.run(
        [*STUDY, "serve", "--port", "8123", "--experimenter-port", "8123", "--db", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "--port and --experimenter-port are both 8123" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not any(tmp_path.iterdir())


def test_serve_port_error_end_to_end() -> None:
    """The real command line: one line of usage error, no traceback."""
    proc = subprocess.run(
        [*STUDY, "serve", "--port", "99999"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "argument --port: must be a TCP port from 1 to 65535" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_argument_types() -> None:
    assert port("8080") == 8080
    assert rate_hz(100.0)("100") == 100.0
    assert non_negative_float("0") == 0.0
    for parse, text in [
        (port, "65536"),
        (rate_hz(100.0), "0"),
        (rate_hz(100.0), "100.01"),
        (non_negative_float, "-0.1"),
        (non_negative_float, "nan"),
    ]:
        with pytest.raises(argparse.ArgumentTypeError):
            parse(text)


def test_trial_noise_must_be_finite_and_non_negative(capsys: pytest.CaptureFixture[str]) -> None:
    from study.cli import trial as trial_cli

    parser = argparse.ArgumentParser()
    trial_cli.add_arguments(parser)
    with pytest.raises(SystemExit):
        parser.parse_args(["--noise", "nan"])
    assert "argument --noise: must be in [0, 0.1], got nan" in capsys.readouterr().err


# ---- protocol nesting ---------------------------------------------------------------------------
def test_deeply_nested_protocol_is_a_typed_error_not_a_recursion_error(tmp_path: Path) -> None:
    path = tmp_path / "deep.toml"
    path.write_text("schema = 1\n\nx = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(ProtocolSyntaxError) as exc:
        load_protocol(path)
    assert exc.value.key == "line 3"
    assert f"nested more than {MAX_NESTING} levels deep" in exc.value.problem
    assert str(path) in str(exc.value)


def test_deep_inline_tables_are_refused_too() -> None:
    text = "x = " + "{a = " * 1000 + "1" + "}" * 1000
    with pytest.raises(ProtocolSyntaxError, match="nested more than"):
        parse_protocol(text)


def test_the_limit_leaves_real_protocols_alone() -> None:
    text = (ROOT / "protocols" / "dragan2013.toml").read_text(encoding="utf-8")
    depth, _ = nesting_depth(text)
    assert depth < MAX_NESTING
    # brackets inside strings and comments are not nesting
    assert nesting_depth('a = "[[[[" # [[[[\nb = \'[[\'\nc = """\n[[[\n"""\nd = [[1]]') == (2, 6)


def test_nesting_at_the_limit_reaches_the_validator() -> None:
    """32 levels parse (the key is then refused as unknown, by name); 33 do not."""
    with pytest.raises(Exception, match="unknown key 'x'"):
        parse_protocol("x = " + "[" * MAX_NESTING + "]" * MAX_NESTING)
    with pytest.raises(ProtocolSyntaxError, match="nested more than"):
        parse_protocol("x = " + "[" * (MAX_NESTING + 1) + "]" * (MAX_NESTING + 1))


def test_the_old_app_commands_say_where_they_moved() -> None:
    """``python -m app serve ...`` (the README's command before the re-layout) names its new
    home with the same options instead of failing with argparse's usage text."""
    done = subprocess.run(
        [sys.executable, "-m", "app", "serve", "--db", "data/x.db"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
    )
    assert done.returncode == 2
    assert "run `python -m study serve --db data/x.db`" in done.stderr


# ---- issue 22: every flag a range, every path a kind, every error one line ----------------------
def parser_of(module: object) -> argparse.ArgumentParser:
    parser = OneLineParser(prog="cmd")
    module.add_arguments(parser)  # type: ignore[attr-defined]
    return parser


def refused(module: object, argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """The one line a command's parser prints for ``argv`` (exit code 2)."""
    with pytest.raises(SystemExit) as exit_:
        parser_of(module).parse_args(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "usage:" not in err
    return err


@pytest.mark.parametrize(
    ("command", "argv", "message"),
    [
        ("schedule", ["--participants", "1000000"], "--participants: must be 1..10000"),
        ("run", ["--db", "x", "--participant", "P", "--schedule-row", "1000000000"], "0..99999"),
        ("run", ["--db", "x", "--participant", "P", "--seed", str(2**63)], "--seed: must be"),
        ("run", ["--db", "x", "--participant", "P", "--demographics", "[" * 60_000], "at most"),
        ("run", ["--db", "x", "--participant", "P", "--demographics", "[" * 4000], "too deeply"),
        (
            "run",
            ["--db", "x", "--participant", "P", "--demographics", '{"a":{"b":{"c":{"d":{}}}}}'],
            "levels deep",
        ),
        ("trial", ["--speed", "1e308"], "--speed: must be in (0, 2]"),
        ("trial", ["--time-limit", "1e9"], "--time-limit: must be in (0, 3600]"),
        (
            "trial",
            ["--save", "/nonexistent-folder/r.npz"],
            "the folder /nonexistent-folder does not exist",
        ),
        ("simulate", ["--db", "x", "--scheduler", "notaurl"], "a scheduler address such as"),
        ("simulate", ["--db", "x", "--participants", "1e9"], "--participants: must be"),
        ("simulate", ["--db", "x", "--workers", "100000"], "--workers: must be 1..256"),
        ("sweep", ["--out", __file__], "is a file, not a folder"),
        ("sweep", ["--out", "x", "--timid-alpha-max", "7"], "must be in [0, 1]"),
        ("render", ["--width", "100000"], "--width: must be 16..4096"),
        ("serve", ["--host", "999.1.1.1"], "--host: must be an IP address"),
        ("serve", ["--priority", "-21"], "--priority: must be -20..19"),
        ("serve", ["--realtime", "1"], "--realtime: must be 0 or 2..99"),
        ("export", ["--db", "x", "--out", __file__], "is a file, not a folder"),
    ],
)
def test_each_flag_has_a_range_and_each_path_a_kind(
    command: str, argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    module = importlib.import_module(f"study.cli.{command}")
    assert message in refused(module, argv, capsys)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--db", "x", "--out", "o", "--n", "1000000"], "--n: must be 2..10000"),
        (["--db", "x", "--out", "o", "--b", "1000000"], "--b: must be 1..100000"),
        (["--db", "x", "--out", "o", "--alpha", "2"], "--alpha: must be in (0, 0.5]"),
    ],
)
def test_power_flags_have_ranges(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from analysis.cli import power

    assert message in refused(power, argv, capsys)


def test_power_refuses_an_allocation_its_input_does_not_justify(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--n 10000 --b 100000 would hold 1e9 resampled participants (about 640 GB): refused
    before the store is even read."""
    from analysis.cli import power

    args = parser_of(power).parse_args(
        [
            "--db",
            str(tmp_path / "absent.db"),
            "--out",
            str(tmp_path / "o"),
            "--n",
            "10000",
            "--b",
            "100000",
        ]
    )
    assert power.main(args) == 2
    assert "at most 1,000,000" in capsys.readouterr().err


def test_serve_names_an_address_this_machine_does_not_have_not_a_port_in_use() -> None:
    problem = serve._cannot_listen("10.255.255.254", 8080)
    assert problem is not None and "no such address" in problem


def test_serve_under_an_unreachable_folder_is_one_line(tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            *STUDY,
            "serve",
            "--db",
            "/proc/no-such-folder/study.db",
            "--port",
            "0",
            "--experimenter-port",
            "0",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "/proc/no-such-folder" in lines[0], proc.stderr


def test_an_unexpected_error_is_one_line_and_ctrl_c_no_traceback(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A command that raises what it did not expect (a bug) still prints one line."""
    broken = types.ModuleType("broken_command")
    broken.add_arguments = lambda parser: None  # type: ignore[attr-defined]

    def main(args: object) -> int:
        raise KeyError("deep inside")

    broken.main = main  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "broken_command", broken)
    monkeypatch.delenv("STUDY_TRACEBACK", raising=False)
    assert dispatch("prog", "", {"go": ("broken_command", "a broken command")}, ["go"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "KeyError" in err and "Traceback" not in err

    def interrupted(args: object) -> int:
        raise KeyboardInterrupt

    broken.main = interrupted  # type: ignore[attr-defined]
    assert dispatch("prog", "", {"go": ("broken_command", "a broken command")}, ["go"]) == 130
    assert "Traceback" not in capsys.readouterr().err

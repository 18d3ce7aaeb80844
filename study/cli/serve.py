"""``python -m study serve``: start the study server (participant view on the LAN, experimenter
view on 127.0.0.1) and print both URLs. Stop with Ctrl-C; running trials are then marked
interrupted and every session can be continued by enrolling the same participant ID again."""

from __future__ import annotations

import argparse
import errno
import ipaddress
import signal
import socket
import sys
import threading
from pathlib import Path
from urllib.parse import urlsplit

from study import scheduling
from study.cli.arguments import float_range, rate_hz
from study.cli.arguments import port as port_number
from study.cli.dispatch import UsageError
from study.errors import StudyError
from study.protocol import load_protocol
from study.protocol.preflight import check_scenes
from study.server import logs, realtime
from study.server.forwarded import trusted_networks
from study.server.link_places import LINK_IDLE_S
from study.server.live import session_factory
from study.server.open_files import raise_open_files_limit
from study.server.server import StudyServer
from study.session import open_store

MAX_RENDER_HZ = 60.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    _study_arguments(parser)
    _network_arguments(parser)
    _online_arguments(parser)
    _operation_arguments(parser)


def _study_arguments(parser: argparse.ArgumentParser) -> None:
    """What runs: the protocol and the store."""
    group = parser.add_argument_group("study")
    group.add_argument(
        "--protocol",
        type=Path,
        default=Path("protocols/dragan2013.toml"),
        help="study protocol (TOML); default: %(default)s",
    )
    group.add_argument(
        "--db", type=Path, default=Path("data/study.db"), help="study store; default: %(default)s"
    )


def _network_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the two views listen, how often the scene updates, one machine or many."""
    group = parser.add_argument_group("network")
    group.add_argument(
        "--host",
        type=host_address,
        default="0.0.0.0",
        help="participant view address (LAN): an IP address of this machine, or 0.0.0.0 for"
        " all; default: %(default)s",
    )
    group.add_argument(
        "--port",
        type=port_number,
        default=8080,
        help="participant view port, 1-65535 (0: any free port); default: %(default)s",
    )
    group.add_argument(
        "--experimenter-port",
        type=port_number,
        default=8081,
        help="experimenter view port (always bound to 127.0.0.1), 1-65535 (0: any free port); "
        "default: %(default)s",
    )
    group.add_argument(
        "--render-hz",
        type=rate_hz(MAX_RENDER_HZ),
        default=MAX_RENDER_HZ,
        help="scene updates per second, above 0 and at most %(default)g (viser sends at most "
        "one pose update per 1/60 s)",
    )
    group.add_argument(
        "--kiosk",
        action="store_true",
        help="one participant machine at a time: a tab joins the one open session without a code",
    )
    group.add_argument(
        "--share",
        action="store_true",
        help="allow viser's public share link (off by default: a study is never published)",
    )


def _online_arguments(parser: argparse.ArgumentParser) -> None:
    """Online studies: the open-enrolment link and a TLS proxy in front."""
    group = parser.add_argument_group("online studies")
    group.add_argument(
        "--open-link",
        type=places,
        default=0,
        metavar="PLACES",
        help="turn the open-enrolment link on with this many places (online studies: a tab"
        " whose URL carries PROLIFIC_PID or pid gets a session without a join code); default:"
        " off (the console turns it on and off)",
    )
    group.add_argument(
        "--link-idle",
        type=float_range(1.0, 1440.0),
        default=LINK_IDLE_S / 60.0,
        metavar="MINUTES",
        help="an open-link session left before consent, with no tab, gives its place back"
        " after this many minutes, 1..1440 (its ID coming back gets it again); default:"
        " %(default)g",
    )
    group.add_argument(
        "--trusted-proxy",
        action="append",
        default=[],
        metavar="ADDR",
        help="a TLS reverse proxy's address or network (repeatable): connections from it count"
        " under the client address it appends to X-Forwarded-For, and the Origin check accepts"
        " the host name it forwards",
    )
    group.add_argument(
        "--public-url",
        default=None,
        metavar="URL",
        help="the participants' address as they reach it behind the proxy (e.g."
        " https://study.example.org), printed and shown with the open link",
    )


def _operation_arguments(parser: argparse.ArgumentParser) -> None:
    """The log, the scheduling priority."""
    group = parser.add_argument_group("operation")
    group.add_argument(
        "--log",
        type=Path,
        default=None,
        help="the server's log file, rotated (at most"
        f" {(logs.BACKUPS + 1) * logs.MAX_BYTES // 2**20} MB in {logs.BACKUPS + 1} files);"
        " default: serve.log beside the store",
    )
    group.add_argument(
        "--priority",
        type=nice_value,
        default=-10,
        help="the server's scheduling priority as a nice value, -20..19 (lower runs first:"
        " the control loops then keep their rate when browsers or other work share the"
        " machine; below 0 needs the right to raise priority, see README); default:"
        " %(default)s",
    )
    group.add_argument(
        "--realtime",
        type=realtime_priority,
        default=10,
        help="real-time scheduling: the control loops' priority, 2..99, the rest of the server"
        " at 1 (the kernel's round-robin class: the server runs as soon as it can, ahead of"
        " browsers and ordinary work, a due control tick first; same right as --priority"
        " below 0), or 0 for none; default: %(default)s",
    )
    group.add_argument("--verbose", action="store_true", help="log viser connections")


def places(text: str) -> int:
    """``--open-link``: a whole number of places, 0..100000."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be a whole number of places, got {text!r}"
        ) from None
    if not 0 <= value <= 100_000:
        raise argparse.ArgumentTypeError(f"must be 0..100000 places, got {value}")
    return value


def public_url(text: str | None) -> str | None:
    """``--public-url``: an http(s) URL of a host, without query or fragment."""
    if text is None:
        return None
    parts = urlsplit(text)
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.query or parts.fragment:
        raise UsageError(
            f"--public-url {text!r} is not an http(s) address such as https://study.example.org"
        )
    return text.rstrip("/")


def host_address(text: str) -> str:
    """argparse type: an IPv4 or IPv6 address to listen on, or ``localhost``."""
    if text == "localhost":
        return text
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be an IP address of this machine (e.g. 0.0.0.0 or 192.168.1.20), got {text!r}"
        ) from None


def nice_value(text: str) -> int:
    """argparse type: a nice value, -20..19."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number -20..19, got {text!r}") from None
    if not -20 <= value <= 19:
        raise argparse.ArgumentTypeError(f"must be -20..19, got {value}")
    return value


def realtime_priority(text: str) -> int:
    """argparse type: a real-time priority 2..99, or 0 for none."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be a whole number 0 or 2..99, got {text!r}"
        ) from None
    if not (value == 0 or 2 <= value <= 99):
        raise argparse.ArgumentTypeError(f"must be 0 or 2..99, got {value}")
    return value


def _take_priority(args: argparse.Namespace) -> None:
    """``--priority`` and ``--realtime`` for the calling thread, which every server thread
    started later inherits (Linux keeps both per thread); a refusal is said, not fatal."""
    if realtime.set_priority(args.priority) is None:
        print(
            f"note: the server runs at its normal priority (raising it to {args.priority} was"
            " not allowed; see README, 'Priority')",
            file=sys.stderr,
        )
    if args.realtime and not scheduling.set_realtime(args.realtime):
        print(
            "note: the server runs as ordinary threads (the real-time class was not allowed;"
            " see README, 'Priority')",
            file=sys.stderr,
        )


def main(args: argparse.Namespace) -> int:
    if args.port and args.port == args.experimenter_port:
        print(
            f"error: --port and --experimenter-port are both {args.port}; the two views need "
            "two ports (e.g. 8080 and 8081)",
            file=sys.stderr,
        )
        return 2
    try:
        protocol = load_protocol(args.protocol)
        check_scenes(protocol)  # every scene builds before a participant can join
    except StudyError as exc:  # naming file, key and problem
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for what, host, port in (
        ("participant", args.host, args.port),
        ("experimenter", "127.0.0.1", args.experimenter_port),
    ):
        problem = _cannot_listen(host, port)
        if problem is not None:
            # viser would quietly move to the next free port, and participants would open the
            # URL they were given -- perhaps another server's
            flag = "--port" if what == "participant" else "--experimenter-port"
            print(f"error: {what} view on {host}:{port}: {problem} ({flag})", file=sys.stderr)
            return 2
    proxies = trusted_networks(args.trusted_proxy)  # a StudyError: said by the dispatcher
    public = public_url(args.public_url)
    log_path = args.log or args.db.parent / "serve.log"
    try:
        args.db.parent.mkdir(parents=True, exist_ok=True)
        logs.configure(log_path)
    except OSError as exc:
        print(f"error: cannot use the folder of {args.db} or {log_path}: {exc}", file=sys.stderr)
        return 2
    try:
        store = open_store(args.db, protocol)
    except StudyError as exc:  # not a store, another protocol's, damaged, locked, ...
        print(f"error: cannot open the store {args.db}: {exc}", file=sys.stderr)
        return 2
    _take_priority(args)  # before the servers start their threads, which inherit it
    raise_open_files_limit()  # every connection is an open file
    server = StudyServer(
        session_factory(store, protocol),
        condition_words=protocol.condition_words,
        host=args.host,
        port=args.port,
        experimenter_port=args.experimenter_port,
        render_hz=args.render_hz,
        verbose=args.verbose,
        kiosk=args.kiosk,
        allow_share=args.share,
        open_link=args.open_link,
        link_idle_s=args.link_idle * 60.0,
        public_url=public,
        trusted_proxies=proxies,
        log_path=log_path,
    )
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    participant_url, experimenter_url = server.urls()
    print(f"participant view:  {participant_url}", flush=True)
    print(f"experimenter view: {experimenter_url}  (this machine only)", flush=True)
    if args.open_link:
        print(f"open link ({args.open_link} places): {server.link_url()}", flush=True)
    try:
        stop.wait()
    finally:
        server.stop()
        store.close()
    return 0


def _cannot_listen(host: str, port: int) -> str | None:
    """Why a TCP server could not listen on ``host:port`` now (``None``: it could)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                return (
                    "the port is in use, perhaps by another study server; stop it or choose another"
                )
            if exc.errno == errno.EADDRNOTAVAIL:
                return "this machine has no such address; use one of its own or 0.0.0.0"
            return exc.strerror or str(exc)
    return None

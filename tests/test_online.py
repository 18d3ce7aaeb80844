"""Online-study conventions without a browser: recruitment IDs from a link, the open link's
places, the completion code and redirect of a protocol, the end screen, and the client address
behind a trusted reverse proxy (only the hop the proxy appended counts)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import viser
from websockets.datastructures import Headers

from study.cli.serve import public_url
from study.export import tidy_tables
from study.protocol import BlindingError, ProtocolValueError, load_protocol
from study.server.firewall import Firewall, FirewallConfig
from study.server.forwarded import accepted_hosts, client_address, trusted_networks
from study.server.live.texts import CLOSE_TEXT, end_screen
from study.server.open_link import LinkClosed, OpenLink
from study.server.recruitment import LinkError, Recruitment, parse_ids, parse_message
from study.session import Session, open_store
from tests.protocol_copies import short_protocol, with_completion

PID = "5f3c1a2b3c4d5e6f7a8b9c0d"
STUDY = "60aa11bb22cc33dd44ee55ff"
PROXY = trusted_networks(["127.0.0.1"])


# -- recruitment IDs ---------------------------------------------------------------------------
def test_a_prolific_link_carries_the_participant_study_and_session_ids() -> None:
    rec = parse_ids({"PROLIFIC_PID": PID, "STUDY_ID": STUDY, "SESSION_ID": "s1"})
    assert rec is not None and rec.key == f"PROLIFIC_PID:{PID}"
    assert rec.as_dict() == {"PROLIFIC_PID": PID, "STUDY_ID": STUDY, "SESSION_ID": "s1"}
    assert parse_ids({"pid": "sona-4711"}) == Recruitment((("pid", "sona-4711"),))
    assert parse_ids({"STUDY_ID": STUDY}) is None  # no participant ID: the join code applies
    assert parse_ids({}) is None


@pytest.mark.parametrize(
    "value",
    ["{{%PROLIFIC_PID%}}", "a" * 41, "", "x y", "<script>", "ä", "a/b", "a.b", "1;DROP"],
)
def test_a_recruitment_id_must_be_a_short_plain_token(value: str) -> None:
    with pytest.raises(LinkError, match="PROLIFIC_PID is not 1-40 letters") as info:
        parse_ids({"PROLIFIC_PID": value})
    if value:
        assert value not in str(info.value)  # the message never repeats the value


def test_page_messages_name_only_known_parameters() -> None:
    assert parse_message(f"P={PID}") == ("PROLIFIC_PID", PID)
    assert parse_message("p=abc") == ("pid", "abc")
    assert parse_message("X=abc") is None and parse_message("P") is None


# -- the open link's places --------------------------------------------------------------------
def test_the_open_link_is_off_by_default_counts_places_and_survives_a_restart(
    tmp_path: Path,
) -> None:
    protocol = load_protocol(short_protocol(tmp_path))
    store = open_store(tmp_path / "s.db", protocol)
    link = OpenLink(store)
    a = Recruitment((("PROLIFIC_PID", PID),))
    b = Recruitment((("pid", "B2"),))
    with pytest.raises(LinkClosed, match="off"):
        link.claim(a)
    with pytest.raises(ValueError, match="at least one place"):
        link.configure(enabled=True, cap=0)
    link.configure(enabled=True, cap=1)
    who = link.claim(a)
    assert who == "L0001"
    Session.enrol(store, protocol, who, recruitment=a.as_dict()).close()
    link.taken(who, a)
    assert link.participant_for(a) == "L0001" and link.used() == 1
    with pytest.raises(LinkClosed, match="all 1 places"):
        link.claim(b)
    enrol = next(e for e in store.events(participant="L0001") if e.kind == "enrol")
    assert enrol.detail["recruitment"] == {"PROLIFIC_PID": PID}
    Session.enrol(store, protocol, "P01").close()  # enrolled in the console
    sessions = tidy_tables(store)["sessions"].set_index("participant")
    assert sessions.loc["L0001", ["source", "prolific_pid"]].tolist() == ["link", PID]
    assert sessions.loc["P01", "source"] == "console" and sessions["pid"].isna().all()
    again = OpenLink(store, enabled=True, cap=2)  # a restarted server
    assert again.participant_for(a) == "L0001" and again.used() == 1
    assert again.claim(b) == "L0002"
    store.close()


def test_one_address_gets_a_few_new_ids_an_hour_and_its_known_ids_always(tmp_path: Path) -> None:
    """A script from 8 addresses once filled 50 places in 20 s with made-up IDs."""
    protocol = load_protocol(short_protocol(tmp_path))
    store = open_store(tmp_path / "s.db", protocol)
    link = OpenLink(store, enabled=True, cap=50, per_address=2)
    for k in range(2):
        ids = Recruitment((("pid", f"bot{k}"),))
        who = link.claim(ids, address="10.0.0.9")
        Session.enrol(store, protocol, who, recruitment=ids.as_dict()).close()
        link.taken(who, ids, address="10.0.0.9")
    with pytest.raises(LinkClosed, match="2 new IDs from one address"):
        link.claim(Recruitment((("pid", "bot2"),)), address="10.0.0.9")
    assert link.claim(Recruitment((("pid", "other"),)), address="10.0.0.10") == "L0003"
    assert link.participant_for(Recruitment((("pid", "bot0"),))) == "L0001"  # comes back
    store.close()


# -- completion code, redirect, end screen ------------------------------------------------------
def test_the_protocol_gives_a_completion_code_and_redirect(tmp_path: Path) -> None:
    url = "https://app.prolific.com/submissions/complete?cc=C0DE1234&p={PROLIFIC_PID}"
    p = load_protocol(with_completion(short_protocol(tmp_path), code="C0DE1234", redirect_url=url))
    assert (p.texts.completion_code, p.texts.redirect_url) == ("C0DE1234", url)
    title, text, redirect = end_screen("completed", p.texts)
    assert title == "Done"
    assert "Your completion code is **C0DE1234**" in text and redirect == url
    assert CLOSE_TEXT not in text  # the page goes back by itself
    _, text, redirect = end_screen("withdrawn", p.texts)
    assert redirect is None and "C0DE1234" not in text and CLOSE_TEXT in text
    (tmp_path / "plain").mkdir()
    plain = load_protocol(short_protocol(tmp_path / "plain"))
    assert end_screen("completed", plain.texts)[2] is None
    assert CLOSE_TEXT in end_screen("completed", plain.texts)[1]


@pytest.mark.parametrize(
    ("code", "url", "problem"),
    [
        ("C0 DE", "", "completion_code"),
        ("", "javascript:alert(1)", "redirect_url"),
        ("", "https://x.org/?a={participant}", "placeholders may only be"),
        ("", 'https://x.org/"onload', "redirect_url"),
    ],
)
def test_bad_completion_fields_are_refused_on_load(
    tmp_path: Path, code: str, url: str, problem: str
) -> None:
    path = with_completion(short_protocol(tmp_path), code=code, redirect_url=url)
    with pytest.raises(ProtocolValueError, match=problem):
        load_protocol(path)


def test_a_redirect_or_code_naming_a_condition_is_refused(tmp_path: Path) -> None:
    path = with_completion(short_protocol(tmp_path), redirect_url="https://x.org/?g=timid")
    with pytest.raises(BlindingError, match=r"debrief\.redirect_url"):
        load_protocol(path)


# -- behind a trusted proxy --------------------------------------------------------------------
def test_only_the_hop_the_trusted_proxy_appended_counts() -> None:
    forged = Headers([("X-Forwarded-For", "6.6.6.6, 10.1.2.3")])
    assert client_address("127.0.0.1", forged, trusted=PROXY) == "10.1.2.3"
    assert client_address("192.0.2.9", forged, trusted=PROXY) == "192.0.2.9"  # not a proxy
    assert client_address("127.0.0.1", forged, trusted=()) == "127.0.0.1"
    two = Headers([("X-Forwarded-For", "6.6.6.6"), ("X-Forwarded-For", "10.9.9.9")])
    assert client_address("127.0.0.1", two, trusted=PROXY) == "10.9.9.9"
    v6 = Headers([("Forwarded", 'for=6.6.6.6, for="[2001:db8::7]:4711";proto=https')])
    assert client_address("127.0.0.1", v6, trusted=PROXY) == "2001:db8::7"
    for bad in ("unknown", "_hidden", "not-an-ip", "", "1.2.3.4.5", "x" * 5000):
        h = Headers([("X-Forwarded-For", f"1.1.1.1, {bad}")])
        assert client_address("127.0.0.1", h, trusted=PROXY) == "127.0.0.1", bad
    assert client_address("127.0.0.1", Headers(), trusted=PROXY) == "127.0.0.1"
    # a client's own long X-Forwarded-For (the proxy appends to it) once made the server read
    # a Forwarded header the client wrote instead: any address it liked, per connection
    long = Headers(
        [("X-Forwarded-For", "1.1.1.1," * 400 + " 10.1.2.3"), ("Forwarded", "for=6.6.6.6")]
    )
    assert client_address("127.0.0.1", long, trusted=PROXY) == "10.1.2.3"
    nets = trusted_networks(["10.0.0.0/8", "::1"])
    assert client_address("10.200.0.1", forged, trusted=nets) == "10.1.2.3"
    with pytest.raises(ValueError, match="not an IP address or network"):
        trusted_networks(["proxy.example.org"])


def test_the_origin_check_accepts_the_public_host_only_from_the_proxy() -> None:
    h = Headers([("Host", "127.0.0.1:8080"), ("X-Forwarded-Host", "study.example.org")])
    assert "study.example.org" in accepted_hosts("127.0.0.1", h, trusted=PROXY)
    assert accepted_hosts("192.0.2.9", h, trusted=PROXY) == {"127.0.0.1:8080"}
    padded = Headers(
        [("X-Forwarded-Host", "a," * 2000 + "study.example.org"), ("Forwarded", "host=evil")]
    )
    assert "evil" not in accepted_hosts("127.0.0.1", padded, trusted=PROXY)
    fw = Firewall(FirewallConfig(trusted_proxies=PROXY))

    def request(origin: str) -> SimpleNamespace:
        offered = ("Sec-WebSocket-Protocol", f"viser-v{viser.__version__}")
        return SimpleNamespace(headers=Headers([*h.raw_items(), ("Origin", origin), offered]))

    conn = SimpleNamespace(remote_address=("127.0.0.1", 5000))
    assert fw.door.problem(conn, request("https://study.example.org")) is None
    assert "origin" in str(fw.door.problem(conn, request("https://evil.example.org")))
    assert fw.client_host(conn, Headers([("X-Forwarded-For", "10.0.0.5")])) == "10.0.0.5"


def test_the_public_url_is_an_http_address_of_a_host() -> None:
    assert public_url("https://study.example.org/") == "https://study.example.org"
    for bad in ("study.example.org", "ftp://x.org", "https://x.org/?a=1", "https://"):
        with pytest.raises(ValueError, match="not an http"):
            public_url(bad)


def test_serve_refuses_a_trusted_proxy_that_is_not_an_address(tmp_path: Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "study",
            "serve",
            "--trusted-proxy",
            "nginx",
            "--db",
            str(tmp_path / "s.db"),
            "--port",
            "0",
            "--experimenter-port",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "python -m study serve: error: --trusted-proxy 'nginx' is not an IP address or network"
        " (e.g. 127.0.0.1 or 10.0.0.0/8)"
    ]

"""The participant page's HTML head: viser's own notices are hidden before its client runs."""

from __future__ import annotations

import gzip
import urllib.request
from pathlib import Path

from websockets.datastructures import Headers
from websockets.http11 import Response

from study.server.page_head import HEAD_STYLE, PageHead
from study.server.page_script import HIDDEN_NOTICES
from tests.browser.harness import start_server

HTML = b"<html><head><title>viser</title></head><body></body></html>"


def _response(body: bytes, content_type: str, *, zipped: bool = False) -> Response:
    payload = gzip.compress(body) if zipped else body
    headers = Headers(
        {
            "Content-Type": content_type,
            "Content-Length": str(len(payload)),
            "Content-Encoding": "gzip" if zipped else "identity",
        }
    )
    return Response(200, "OK", headers, payload)


def test_the_page_gets_the_style_before_its_head_ends_plain_or_gzipped() -> None:
    head = PageHead()
    for zipped in (False, True):
        out = head(None, _response(HTML, "text/html; charset=utf-8", zipped=zipped))
        body = gzip.decompress(out.body) if zipped else out.body
        assert body.index(HEAD_STYLE.encode()) < body.index(b"</head>")
        assert out.headers["Content-Length"] == str(len(out.body))
        assert out.headers["Content-Encoding"] == ("gzip" if zipped else "identity")
        for notice in HIDDEN_NOTICES:
            assert f"#{notice}".encode() in body


def test_other_responses_pass_unchanged() -> None:
    head = PageHead()
    script = _response(b"console.log('</head>')", "application/javascript")
    assert head(None, script) is script
    missing = Response(404, "NOT FOUND", Headers(), b"")
    assert head(None, missing) is missing
    assert head(None, None) is None  # a websocket upgrade: viser answers nothing


def test_the_served_page_hides_viewers_notices_from_the_first_paint(tmp_path: Path) -> None:
    rs = start_server(tmp_path)
    try:
        with urllib.request.urlopen(rs.url + "/", timeout=10) as reply:
            page = reply.read()
        assert HEAD_STYLE.encode() in page and page.index(HEAD_STYLE.encode()) < page.index(
            b"</head>"
        )
        with urllib.request.urlopen(rs.console_url + "/", timeout=10) as reply:
            console = reply.read()
        assert HEAD_STYLE.encode() not in console  # the experimenter sees viser as it is
    finally:
        rs.stop()

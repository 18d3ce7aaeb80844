"""The participant page's HTML head: what must hold before viser's client runs.

viser's client shows its own notices as it mounts ("Software WebGL rendering detected" on any
machine without a GPU), before the websocket is open and so before the page script
(:mod:`study.server.page_script`) can hide anything: a participant would see it on every load
and reload. :func:`inject_head` rewrites viser's ``index.html`` response on its way out (through
``Firewall.page_filter``) with a ``<style>`` element in the head: the page script's CSS
(:data:`study.server.page_script.PANEL_CHROME_CSS`), in force from the first paint; and a script
that must run before viser's client asks for its WebGL context
(:data:`study.server.software_webgl.SOFTWARE_WEBGL_SCRIPT`: no multisampling on a CPU renderer).
"""

from __future__ import annotations

import gzip
import http
import threading
from typing import Any

from websockets.datastructures import Headers
from websockets.http11 import Response

from study.server.page_script import PANEL_CHROME_CSS
from study.server.software_webgl import SOFTWARE_WEBGL_SCRIPT

HEAD_STYLE = f"<style>{PANEL_CHROME_CSS}</style>"
HEAD = HEAD_STYLE + SOFTWARE_WEBGL_SCRIPT
"""What the participant page's head gets."""
_HTML = "text/html"


class PageHead:
    """``(request, response) -> response``: the page's HTML gets :data:`HEAD` before
    ``</head>``; any other response passes unchanged. Rewritten pages are cached (viser serves
    the same cached bytes each time)."""

    def __init__(self, head: str = HEAD) -> None:
        self.head = head.encode()
        self._cache: dict[tuple[bytes, bool], bytes] = {}
        self._lock = threading.Lock()

    def __call__(self, _request: Any, response: Any) -> Any:
        if not isinstance(response, Response) or response.status_code != http.HTTPStatus.OK:
            return response
        if not response.headers.get("Content-Type", "").startswith(_HTML):
            return response
        zipped = response.headers.get("Content-Encoding", "") == "gzip"
        key = (bytes(response.body), zipped)
        with self._lock:
            body = self._cache.get(key)
            if body is None:
                body = self._cache[key] = self._rewrite(key[0], zipped=zipped)
        headers = Headers(
            [(k, v) for k, v in response.headers.raw_items() if k.lower() != "content-length"]
        )
        headers["Content-Length"] = str(len(body))
        return Response(response.status_code, response.reason_phrase, headers, body)

    def _rewrite(self, body: bytes, *, zipped: bool) -> bytes:
        html = gzip.decompress(body) if zipped else body
        at = html.find(b"</head>")
        if at < 0:
            return body
        html = html[:at] + self.head + html[at:]
        return gzip.compress(html) if zipped else html


__all__ = ["HEAD", "HEAD_STYLE", "PageHead"]

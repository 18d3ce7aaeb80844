"""Recruitment IDs from the participant link's URL, and the way back to the recruitment site.

Online panels send participants to a study with their IDs in the link's query string; Prolific's
convention is ``?PROLIFIC_PID=...&STUDY_ID=...&SESSION_ID=...``; other panels (SONA, MTurk
wrappers, a mailing list) use a generic ``pid``. The tab's own page reads them
(:func:`link_script`: the server never sees the page's URL, only its websocket) and sends each,
cut to ``MAX_ID + 1`` characters, as a value of one hidden text element: ``"<key>=<value>"``
then ``"."`` when done (a GUI value of at most 64 characters, as the firewall allows). The
element's values are never echoed (:func:`study.server.viser_door.stop_echo`).

Hostile ground: each value must be 1-``MAX_ID`` letters, digits, ``-`` or ``_``
(:func:`parse_ids`; Prolific's IDs are 24 hexadecimal digits), else the link is refused with a
neutral message. Nothing read here is ever sent back to the participant's page: not shown, not
echoed (viser does not echo a tab's own GUI value), not put into a URL the server sends. The
way back (:func:`redirect_script`) fills the protocol's ``{PROLIFIC_PID}``-style placeholders in
the browser, from the browser's own URL, so a recruitment ID that happens to hold a condition
word never travels from the server.
"""

from __future__ import annotations

import contextlib
import json
import re
import threading
from collections.abc import Mapping
from dataclasses import dataclass

from study.errors import StudyError
from study.server import viser_door
from study.server.participant_page import ParticipantPage

PARAMS: dict[str, str] = {"PROLIFIC_PID": "P", "STUDY_ID": "S", "SESSION_ID": "E", "pid": "p"}
"""URL parameters read, and the one-letter key each travels under."""
ID_PARAMS = ("PROLIFIC_PID", "pid")
"""The parameters that name the participant (the first present is their recruitment ID)."""
MAX_ID = 40
ID_PATTERN = re.compile(rf"[A-Za-z0-9_-]{{1,{MAX_ID}}}", re.ASCII)
LINK_WAIT_S = 15.0
"""How long the server waits for a new tab to say what its URL carries (a browser answers
within a round trip once its page runs; a loaded machine or phone can take seconds, and a tab
that has not answered by then is offered the join code)."""


class LinkError(StudyError, ValueError):
    """The link's recruitment parameters are not usable (the message names which, never the
    value)."""


@dataclass(frozen=True)
class Recruitment:
    """The recruitment IDs a link carried: ``ids`` as (URL parameter, value), in ``PARAMS``
    order; ``key`` is the participant's recruitment ID (``PROLIFIC_PID``, else ``pid``)."""

    ids: tuple[tuple[str, str], ...]

    @property
    def key(self) -> str:
        values = dict(self.ids)
        return next(f"{p}:{values[p]}" for p in ID_PARAMS if p in values)

    def as_dict(self) -> dict[str, str]:
        return dict(self.ids)


def parse_ids(values: Mapping[str, str]) -> Recruitment | None:
    """The recruitment of a link's parameters (URL names -> values); ``None`` when it carries
    no participant ID; :class:`LinkError` for a value that is not an ID."""
    ids = []
    for name in PARAMS:
        value = values.get(name)
        if value is None:
            continue
        if not isinstance(value, str) or not ID_PATTERN.fullmatch(value):
            raise LinkError(
                f"URL parameter {name} is not 1-{MAX_ID} letters, digits, '-' or '_'"
                " (was the recruitment site's placeholder filled in?)"
            )
        ids.append((name, value))
    if not any(name in ID_PARAMS for name, _ in ids):
        return None
    return Recruitment(tuple(ids))


def parse_message(text: str) -> tuple[str, str] | None:
    """One ``"<key>=<value>"`` message from the page -> (URL parameter, value); ``None`` for
    anything else (an unknown key, no ``=``)."""
    key, sep, value = str(text).partition("=")
    names = {short: name for name, short in PARAMS.items()}
    if not sep or key not in names:
        return None
    return names[key], value


def link_script(*, uuid: str) -> str:
    """JavaScript: send the tab's recruitment parameters to the hidden element ``uuid``."""
    return (
        _LINK.replace("__VISER__", viser_door.CLIENT_GLOBAL)
        .replace("__UUID__", json.dumps(uuid))
        .replace("__PARAMS__", json.dumps(list(PARAMS.items())))
        .replace("__CUT__", str(MAX_ID + 1))
    )


_LINK = r"""
(() => {
  const m = __VISER__;
  if (!m) return;
  const q = new URLSearchParams(window.location.search);
  const send = (v) => m.sendMessage({type: "GuiUpdateMessage", uuid: __UUID__,
                                     updates: {value: v}});
  for (const [name, key] of __PARAMS__) {
    const v = q.get(name);
    if (v !== null) send(key + "=" + v.slice(0, __CUT__));
  }
  send(".");
})();
"""


def read_link(page: ParticipantPage, *, timeout_s: float = LINK_WAIT_S) -> dict[str, str]:
    """Ask ``page`` which recruitment parameters its URL carries (URL name -> raw value, each
    at most ``MAX_ID + 1`` characters); ``{}`` when it says none or does not answer in time."""
    values: dict[str, str] = {}
    done = threading.Event()
    box = page.client.gui.add_text("link", initial_value="", visible=False)
    # viser queues every GUI value a tab sends back to "the other clients" of its handle (none
    # for a tab's own element, but the message is still built): a recruitment ID holding a
    # condition word would then trip the blinding guard. Nothing is to be echoed here.
    viser_door.stop_echo(box)

    async def on_value(_: object) -> None:  # on viser's loop: in arrival order
        text = str(box.value)
        if text == ".":
            done.set()
        elif (item := parse_message(text)) is not None and len(values) < len(PARAMS):
            values[item[0]] = item[1]

    box.on_update(on_value)
    try:
        page.run_script(link_script(uuid=viser_door.element_uuid(box)))
        answered = done.wait(timeout_s)
    finally:
        with contextlib.suppress(Exception):  # the tab closed meanwhile
            box.remove()
    return values if answered else {}


PLACEHOLDERS = tuple(f"{{{name}}}" for name in PARAMS)
"""What a protocol's ``redirect_url`` may contain, filled in by the participant's browser."""


def redirect_script(url: str, *, delay_ms: int = 0) -> str:
    """JavaScript: go to ``url`` after ``delay_ms``, its placeholders filled from the tab's
    own URL (an invalid or missing value becomes empty)."""
    return (
        _REDIRECT.replace("__URL__", json.dumps(url))
        .replace("__NAMES__", json.dumps(list(PARAMS)))
        .replace("__MAX__", str(MAX_ID))
        .replace("__DELAY__", str(max(0, int(delay_ms))))
    )


_REDIRECT = r"""
(() => {
  const q = new URLSearchParams(window.location.search);
  const ok = /^[A-Za-z0-9_-]{1,__MAX__}$/;
  let url = __URL__;
  for (const name of __NAMES__) {
    const v = q.get(name);
    url = url.split("{" + name + "}").join(v !== null && ok.test(v) ? encodeURIComponent(v) : "");
  }
  clearTimeout(window.__studyRedirect);
  window.__studyRedirect = setTimeout(() => window.location.assign(url), __DELAY__);
})();
"""


__all__ = [
    "ID_PARAMS",
    "MAX_ID",
    "PARAMS",
    "PLACEHOLDERS",
    "LinkError",
    "Recruitment",
    "link_script",
    "parse_ids",
    "parse_message",
    "read_link",
    "redirect_script",
]

"""What a message on the participant port may carry: types, sizes and values.

``screen(raw, ...)`` looks at one undecoded websocket message and returns why it is refused
(``None`` when it may be decoded): at most ``max_bytes``; msgpack with a string ``type``; a
type in the allow-list (share-link types only when the experimenter asked for them); every
number finite and bounded (a pose within ``max_position_m`` of the origin, a quaternion of
about unit length, a camera that does not look at its own position), strings and containers
short, GUI updates carrying only ``value``. Reasons are
fixed texts plus the type name, never the payload.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgspec

from study.errors import StudyError
from study.server import viser_door

PARTICIPANT_TYPES: frozenset[str] = frozenset(
    {
        "ViewerCameraMessage",
        "GuiUpdateMessage",
        "TransformControlsUpdateMessage",
        "TransformControlsDragStartMessage",
        "TransformControlsDragEndMessage",
        "LocalStorageGetItemResponseMessage",
    }
)
"""What the participant page needs to send: its camera, GUI values, the handle's pose, and the
join code it kept for a reload (the answer to the server's local-storage request)."""

SHARE_TYPES: frozenset[str] = frozenset({"ShareUrlRequest", "ShareUrlDisconnect"})

LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "::1"})
"""Host names a loopback-only server (the console) answers to: a page whose own name was made
to point at 127.0.0.1 (DNS rebinding) passes the origin check, but not this one."""

MAX_MESSAGE_BYTES = 16 * 1024
"""Largest message a participant's browser sends in normal use is well under 1 KiB."""

MAX_POSITION_M = 3.0
"""Farthest a handle pose may lie from the robot's base (every scene lies within 2 m)."""
MAX_STRING = 64
"""Longest string a page sends: a join code, an answer, a key state, a node name."""
MAX_GUI_TEXT = 8000
"""Longest value of a GUI field: a free-text answer (``study.protocol.items.MAX_TEXT_LENGTH``,
2,000 characters at most) with room for a participant to see a count over the limit before
shortening it. The message limit (``MAX_MESSAGE_BYTES``) still bounds it in bytes."""


@dataclass(eq=False)
class Dropped(viser_door.Message, include_in_scene_serialization=False):
    """Stands in for a refused incoming message; nothing handles it."""

    reason: str


class RefusedMessage(StudyError, ValueError):
    """An incoming message broke a rule; the text says which (never the payload)."""


class ConnectionFlood(StudyError, ConnectionError):
    """A connection sent far more, or far worse, than a page does; it is closed with ``code``
    (1008 policy violation, or 1003 for data viser does not speak)."""

    def __init__(self, why: str, *, code: int = 1008) -> None:
        super().__init__(why)
        self.code = code


def _finite(value: Any, *, bound: float, what: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RefusedMessage(f"{what} is not a number")
    if not math.isfinite(value) or abs(value) > bound:
        raise RefusedMessage(f"{what} is not finite or beyond {bound:g}")


def _vector(value: Any, *, n: int, bound: float, what: str) -> None:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise RefusedMessage(f"{what} is not {n} numbers")
    for x in value:
        _finite(x, bound=bound, what=what)


def _norm(value: Any) -> float:
    return math.sqrt(sum(float(x) * float(x) for x in value))


def _within(value: Any, *, bound: float, what: str) -> None:
    """A 3-vector no farther than ``bound`` from the origin."""
    _vector(value, n=3, bound=bound, what=what)
    if _norm(value) > bound:
        raise RefusedMessage(f"{what} is farther than {bound:g} from the origin")


def _rotation(value: Any, *, what: str) -> None:
    """A quaternion that is one (near unit length), not zero."""
    _vector(value, n=4, bound=2.0, what=what)
    if not 0.5 <= _norm(value) <= 1.5:
        raise RefusedMessage(f"{what} is not a unit quaternion")


def _string(value: Any, *, what: str, limit: int = MAX_STRING) -> None:
    if not isinstance(value, str) or len(value) > limit:
        raise RefusedMessage(f"{what} is not a string of at most {limit} characters")


def _handle_pose(body: dict[str, Any], *, max_position_m: float, max_text: int) -> None:
    _handle_drag(body, max_position_m=max_position_m, max_text=max_text)
    _within(body.get("position"), bound=max_position_m, what="handle position")
    _rotation(body.get("wxyz"), what="handle orientation")


def _handle_drag(body: dict[str, Any], *, max_position_m: float, max_text: int) -> None:
    _string(body.get("name"), what="handle name")
    _string(body.get("owner", ""), what="handle owner")


def _gui_update(body: dict[str, Any], *, max_position_m: float, max_text: int) -> None:
    _string(body.get("uuid"), what="GUI id", limit=64)
    updates = body.get("updates")
    if not isinstance(updates, dict) or set(updates) != {"value"}:
        raise RefusedMessage("GUI update changes something other than its value")
    value = updates["value"]
    if isinstance(value, str):
        _string(value, what="GUI value", limit=max_text)
    elif not isinstance(value, bool):
        _finite(value, bound=1e9, what="GUI value")


def _storage_answer(body: dict[str, Any], *, max_position_m: float, max_text: int) -> None:
    _string(body.get("request_uuid"), what="storage request id", limit=64)
    for key in ("value", "error"):
        if body.get(key) is not None:
            _string(body.get(key), what=f"storage {key}", limit=64)


def _camera(body: dict[str, Any], *, max_position_m: float, max_text: int) -> None:
    for key in ("position", "look_at", "up_direction"):
        _vector(body.get(key), n=3, bound=1e4, what=f"camera {key}")
    _rotation(body.get("wxyz"), what="camera orientation")
    gap = [float(a) - float(b) for a, b in zip(body["position"], body["look_at"], strict=True)]
    if _norm(gap) < 1e-6 or _norm(body["up_direction"]) < 1e-6:
        raise RefusedMessage("camera looks at its own position or has no up direction")
    for key in ("fov", "near", "far"):
        _finite(body.get(key), bound=1e6, what=f"camera {key}")
    for key in ("image_height", "image_width"):
        _finite(body.get(key), bound=1e5, what=f"camera {key}")


_CHECKS: dict[str, Callable[..., None]] = {
    "TransformControlsUpdateMessage": _handle_pose,
    "TransformControlsDragStartMessage": _handle_drag,
    "TransformControlsDragEndMessage": _handle_drag,
    "GuiUpdateMessage": _gui_update,
    "LocalStorageGetItemResponseMessage": _storage_answer,
    "ViewerCameraMessage": _camera,
}
"""The value checks of each message type a page may send (other types: none)."""


def check_values(
    kind: str, body: dict[str, Any], *, max_position_m: float, max_text: int = MAX_GUI_TEXT
) -> None:
    """Raise :class:`RefusedMessage` unless ``body`` (a decoded message) is plausible; GUI
    text values of at most ``max_text`` characters."""
    check = _CHECKS.get(kind)
    if check is not None:
        check(body, max_position_m=max_position_m, max_text=max_text)


def reason_kind(reason: str) -> str:
    """The kind of a refusal, without what the client chose (a size, a message type it made
    up): the key its count and its log line go by, so that a client cannot make one log line
    per size or per type name. A value check's kind keeps the type, one of a few."""
    if reason.startswith("message of "):
        return "oversize message"
    if reason.startswith("undecodable message"):
        return "undecodable message"
    if reason.endswith(" is not accepted here"):
        return "a type not accepted here"
    if "(share links are off" in reason:
        return "share link (off)"
    return reason.split(":")[0].split(" (")[0]


def is_value_refusal(reason: str) -> bool:
    """The refusal is of a known message type's values (a pose too far, a text too long), not
    of the message's size, form or type: what an honest page can still send by accident."""
    return reason.split(":")[0] in _CHECKS


def screen(
    raw: bytes,
    *,
    max_bytes: int,
    allowed: frozenset[str] | None,
    allow_share: bool,
    max_position_m: float,
    max_text: int = MAX_GUI_TEXT,
) -> str | None:
    """``None`` when ``raw`` may be decoded, else the reason it is refused (``allowed=None``:
    every type, no value rules -- the console, whose reasons may be long)."""
    if len(raw) > max_bytes:
        return f"message of {len(raw)} bytes (limit {max_bytes})"
    try:
        body = msgspec.msgpack.decode(raw)
    except Exception:  # not msgpack, or nested too deep to decode
        return "not a viser message"
    if not isinstance(body, dict) or not isinstance(body.get("type"), str):
        return "not a viser message"
    kind = body["type"]
    if kind in SHARE_TYPES and not allow_share:
        return f"{kind} (share links are off; start the server with --share to allow them)"
    if allowed is not None and kind not in allowed:
        known = viser_door.is_message_type(kind)
        return f"{kind if known else 'an unknown type'} is not accepted here"
    if allowed is None:
        return None
    try:
        check_values(kind, body, max_position_m=max_position_m, max_text=max_text)
    except RefusedMessage as exc:
        return f"{kind}: {exc}"
    except Exception:  # a structure too odd to inspect (e.g. nested too deep)
        return f"{kind}: not inspectable"
    return None

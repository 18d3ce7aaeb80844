"""What the participant's page sends, read as hostile: each value parsed or refused.

A value that does not parse raises :class:`InputRejected` with a short message (never the whole
payload); the page ignores the input and records the problem (``ParticipantPage.reject``).
"""

from __future__ import annotations

import re

import numpy as np

from study.errors import StudyError
from study.server.draw_rate import MAX_DRAW_HZ
from study.server.firewall import MAX_POSITION_M
from study.server.page_script import ARROW_KEYCODES, MAX_KEY_MESSAGE, STEERING_CODES

KEY_LETTERS = frozenset(STEERING_CODES.values()) | frozenset(ARROW_KEYCODES.values())
_KEY_STATE = re.compile(r"([0-9]{1,12}) ([a-z]*)", re.ASCII)


class InputRejected(StudyError, ValueError):
    """A message from the browser was malformed (NaN pose, unknown answer); it was ignored."""


def parse_answer(value: object, *, points: int) -> int:
    """The integer answer 1..points in ``value`` (a button label), else :class:`InputRejected`."""
    try:
        answer = int(str(value))
    except ValueError:
        raise InputRejected(f"answer {value!r} is not a number 1..{points}") from None
    if not 1 <= answer <= points:
        raise InputRejected(f"answer {answer} is outside 1..{points}")
    return answer


def parse_position(position: object) -> np.ndarray:
    """A finite 3-vector within ``MAX_POSITION_M`` of the origin, else :class:`InputRejected`
    (whose message is short: never the whole payload)."""
    try:
        p = np.asarray(position, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise InputRejected("gizmo position is not numeric") from None
    if p.shape != (3,):
        raise InputRejected(f"gizmo position has {p.size} values, not 3")
    if not np.all(np.isfinite(p)) or float(np.max(np.abs(p))) > MAX_POSITION_M:
        raise InputRejected(f"gizmo position is not finite or beyond {MAX_POSITION_M:g} m")
    return p


def parse_key_state(value: object) -> tuple[int, frozenset[str]]:
    """``"<seq> <letters>"`` -> (seq, held keys), else :class:`InputRejected`."""
    text = str(value)
    if len(text) > MAX_KEY_MESSAGE:
        raise InputRejected(f"key state of {len(text)} characters")
    match = _KEY_STATE.fullmatch(text)
    if match is None or not set(match[2]) <= KEY_LETTERS:
        raise InputRejected("key state is not '<number> <keys>'")
    return int(match[1]), frozenset(match[2])


def parse_draw_rate(value: object) -> float:
    """The page's frames a second, ``"<1..MAX_DRAW_HZ>"`` (digits only), else
    :class:`InputRejected`."""
    text = str(value)
    if not (0 < len(text) <= len(str(MAX_DRAW_HZ)) and text.isascii() and text.isdigit()):
        raise InputRejected("draw rate is not a whole number of frames a second")
    hz = int(text)
    if not 1 <= hz <= MAX_DRAW_HZ:
        raise InputRejected(f"draw rate {hz} is outside 1..{MAX_DRAW_HZ}")
    return float(hz)

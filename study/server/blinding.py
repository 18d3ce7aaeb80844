"""Blinding guard: no condition name ever reaches the participant's browser.

Two layers, both installed by :func:`install` for one viser server (the participant's):

1. Queue: every message a viser server queues passes through an ``AsyncMessageBuffer`` (the
   broadcast buffer or one per client). ``AsyncMessageBuffer.push`` is wrapped once per
   process; a push on the event loop of a guarded server is checked by that server's
   :class:`BlindingGuard`, which walks every string in the message (values, dict keys, tuple
   items). A message containing a forbidden word (case-insensitive substring, so "bright"
   counts as well as "right") is dropped and logged.
2. Wire: viser mutates the props of already-queued messages in place (a markdown's content
   update also rewrites its creation message), so the queue check alone can be bypassed.
   ``Message.as_serializable_dict``, which viser's sender calls for every message on the
   server's own event loop just before encoding, is wrapped too: any string still carrying a
   forbidden word is blanked in the outgoing dict and the violation logged.

Other servers (the experimenter's) pass through untouched.
"""

from __future__ import annotations

import asyncio
import dataclasses
import logging
import threading
import time
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np
import viser
from viser.infra._async_message_buffer import AsyncMessageBuffer
from viser.infra._messages import Message as _WireMessage

LOGGER = logging.getLogger("study.server.blinding")

CONDITION_WORDS: tuple[str, ...] = ("timid", "aggressive", "right", "wrong", "easy", "hard")
"""Words that name a study condition (factor levels and modes); never sent to a participant."""


class BlindingViolation(RuntimeError):
    """A participant-facing string names a condition. Rephrase the text without the word."""


def find_condition_words(text: str, *, words: Iterable[str] = CONDITION_WORDS) -> list[str]:
    """Return the forbidden words occurring in ``text`` (case-insensitive substrings)."""
    low = text.lower()
    return [w for w in words if w in low]


def check_text(text: str, *, words: Iterable[str] = CONDITION_WORDS) -> str:
    """Return ``text`` unchanged, or raise :class:`BlindingViolation` naming the word found."""
    found = find_condition_words(text, words=words)
    if found:
        raise BlindingViolation(
            f"participant text {text[:80]!r} contains condition word(s) {found}; rephrase it"
        )
    return text


def iter_strings(obj: Any, *, _depth: int = 0) -> Iterator[str]:
    """Yield every string inside a viser message (dataclass fields, mappings, sequences)."""
    if _depth > 32 or obj is None:
        return
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, (bytes, bytearray, memoryview, np.ndarray, int, float, bool)):
        return
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for field in dataclasses.fields(obj):
            yield from iter_strings(getattr(obj, field.name), _depth=_depth + 1)
    elif isinstance(obj, dict):
        for key, value in obj.items():
            if isinstance(key, str):
                yield key
            yield from iter_strings(value, _depth=_depth + 1)
    elif isinstance(obj, (list, tuple, set, frozenset)):
        for item in obj:
            yield from iter_strings(item, _depth=_depth + 1)


@dataclasses.dataclass
class Violation:
    """One blocked message: its type, the offending string (shortened) and the words found."""

    message_type: str
    text: str
    words: tuple[str, ...]


MAX_KEPT = 200
LOG_EVERY_S = 10.0


class BlindingGuard:
    """Checks every outgoing message of one viser server; blocks and records violations (the
    first ``MAX_KEPT`` of them; all are counted) and logs at most one a ``LOG_EVERY_S`` per
    message type, so a client that types condition words into a field and has them echoed
    cannot flood the log or the memory."""

    def __init__(self, *, words: Iterable[str] = CONDITION_WORDS, block: bool = True) -> None:
        self.words = tuple(w.lower() for w in words)
        self.block = block
        self.violations: list[Violation] = []
        """The first ``MAX_KEPT`` violations (``blocked`` counts them all)."""
        self.blocked = 0
        self.checked = 0
        self.serialized = 0
        self.redacted = 0
        self._lock = threading.Lock()
        self._logged: dict[str, float] = {}

    def _record(self, violation: Violation) -> bool:
        """Keep and count ``violation``; True when it should be logged now."""
        now = time.monotonic()
        with self._lock:
            self.blocked += 1
            if len(self.violations) < MAX_KEPT:
                self.violations.append(violation)
            last = self._logged.get(violation.message_type)
            if last is not None and now - last < LOG_EVERY_S:
                return False
            self._logged[violation.message_type] = now
            return True

    def inspect(self, message: Any) -> Violation | None:
        """Return the first violation in ``message``, or ``None`` when it is clean."""
        for text in iter_strings(message):
            found = find_condition_words(text, words=self.words)
            if found:
                return Violation(type(message).__name__, text[:120], tuple(found))
        return None

    def allow(self, message: Any) -> bool:
        """Record the check; return False when the message must not be sent."""
        violation = self.inspect(message)
        with self._lock:
            self.checked += 1
        if violation is None:
            return True
        if self._record(violation):
            LOGGER.error(
                "blinding: %s %s carrying %r (words %s; %d blocked in all)",
                "blocked" if self.block else "saw",
                violation.message_type,
                violation.text,
                list(violation.words),
                self.blocked,
            )
        return not self.block

    def redact(self, obj: Any, *, message_type: str) -> Any:
        """``obj`` (a serialisable dict tree) with every string naming a condition blanked."""
        if isinstance(obj, str):
            found = find_condition_words(obj, words=self.words)
            if not found:
                return obj
            violation = Violation(message_type, obj[:120], tuple(found))
            with self._lock:
                self.redacted += 1
            if self._record(violation):
                LOGGER.error("blinding: blanked %r in outgoing %s", violation.text, message_type)
            return ""
        if isinstance(obj, dict):
            return {
                k: self.redact(v, message_type=message_type)
                for k, v in obj.items()
                if not (isinstance(k, str) and find_condition_words(k, words=self.words))
            }
        if isinstance(obj, list | tuple):
            return type(obj)(self.redact(v, message_type=message_type) for v in obj)
        return obj


_GUARDS: dict[int, BlindingGuard] = {}
_INSTALL_LOCK = threading.Lock()
_ORIGINAL_PUSH = AsyncMessageBuffer.push
_ORIGINAL_SERIALIZE = _WireMessage.as_serializable_dict


def _guarded_push(self: AsyncMessageBuffer, message: Any) -> None:
    guard = _GUARDS.get(id(self.event_loop))
    if guard is not None and not guard.allow(message):
        return
    _ORIGINAL_PUSH(self, message)


def _guarded_serialize(self: Any, binary_buffers: Any = None) -> dict[str, Any]:
    out = _ORIGINAL_SERIALIZE(self, binary_buffers)
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        return out
    guard = _GUARDS.get(id(loop))
    if guard is None:
        return out
    with guard._lock:
        guard.serialized += 1
    if any(find_condition_words(t, words=guard.words) for t in iter_strings(out)):
        out = guard.redact(out, message_type=type(self).__name__)
    return out


def install(server: viser.ViserServer, guard: BlindingGuard | None = None) -> BlindingGuard:
    """Guard every message ``server`` sends from now on; return the guard."""
    loop = server._websock_server._background_event_loop
    if loop is None:  # pragma: no cover - viser starts its loop in the constructor
        raise RuntimeError("the viser server has no event loop yet; install after it starts")
    guard = guard or BlindingGuard()
    with _INSTALL_LOCK:
        if AsyncMessageBuffer.push is not _guarded_push:
            AsyncMessageBuffer.push = _guarded_push  # type: ignore[method-assign]
        if _WireMessage.as_serializable_dict is not _guarded_serialize:
            _WireMessage.as_serializable_dict = _guarded_serialize  # type: ignore[method-assign]
        _GUARDS[id(loop)] = guard
    return guard


def uninstall(server: viser.ViserServer) -> None:
    """Stop guarding ``server`` (call when it stops)."""
    loop = server._websock_server._background_event_loop
    with _INSTALL_LOCK:
        _GUARDS.pop(id(loop), None)

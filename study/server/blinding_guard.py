"""Blinding guard: no condition name ever reaches the participant's browser.

The words are those of the protocol the server runs (:attr:`study.protocol.Protocol.
condition_words`: every factor level, task and mode name, plus a fixed list), given to
:func:`install`. Our own code checks each text where it hands it to viser (:func:`check_text`,
used by :mod:`study.server.participant_page`); this guard then checks what viser actually sends,
which also covers what viser echoes back (text a tab typed) and names in the 3-D scene.

viser has no public hook on outgoing messages; :mod:`study.server.viser_door` gives one
(:func:`~study.server.viser_door.watch_outgoing`), and the guard is written as policy over it.
Two layers, both installed by :func:`install` for one viser server (the participant's):

1. Queue (:meth:`BlindingGuard.on_queue`): every message the server queues is checked; the guard
   walks every string in the message (values, dict keys, tuple items). A message containing a
   forbidden word (case-insensitive substring, so "bright" counts as well as "right") is
   dropped and logged. viser's echo of what a tab typed, queued on that tab's own connection
   (which never sends it back), is dropped unread and unlogged: a participant's free-text
   answer is data, may hold any word, and must not fill the log as a false leak.
2. Wire (:meth:`BlindingGuard.on_serialize`): viser mutates the props of already-queued messages
   in place (a markdown's content update also rewrites its creation message), so the queue
   check alone can be bypassed. Each message's outgoing dict, made on the server's own event
   loop just before encoding, is checked too: any string still carrying a forbidden word is
   blanked and the violation logged.

A string that is exactly one of viser's own fixed values for the field it sits in passes both
layers (:mod:`study.server.viser_vocabulary`: memory3's level "standard" is also every mesh's
``material``); such a value is the same in every condition.

Other servers (the experimenter's) pass through untouched.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np
import viser

from study.errors import StudyError
from study.protocol.blinding import find_words
from study.server import viser_door
from study.server.viser_vocabulary import is_viser_setting

LOGGER = logging.getLogger("study.server.blinding")


class BlindingViolation(StudyError, RuntimeError):
    """A participant-facing string names a condition. Rephrase the text without the word."""


def check_text(text: str, *, words: Iterable[str]) -> str:
    """Return ``text`` unchanged, or raise :class:`BlindingViolation` naming the word found."""
    found = find_words(text, words)
    if found:
        raise BlindingViolation(
            f"participant text {text[:80]!r} contains condition word(s) {found}; rephrase it"
        )
    return text


def iter_strings(obj: Any, *, _depth: int = 0) -> Iterator[str]:
    """Yield every string inside a viser message (dataclass fields, mappings, sequences),
    except a field's value that is one of viser's own fixed settings for that field
    (:mod:`study.server.viser_vocabulary`: the same in every condition)."""
    if _depth > 32 or obj is None:
        return
    if isinstance(obj, str):
        yield obj
    elif isinstance(obj, (bytes, bytearray, memoryview, np.ndarray, int, float, bool)):
        return
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        fields = ((f.name, getattr(obj, f.name)) for f in dataclasses.fields(obj))
        yield from _field_strings(fields, keys=False, depth=_depth)
    elif isinstance(obj, dict):
        yield from _field_strings(obj.items(), keys=True, depth=_depth)
    elif isinstance(obj, (list, tuple, set, frozenset)):
        for item in obj:
            yield from iter_strings(item, _depth=_depth + 1)


def _field_strings(fields: Iterable[tuple[Any, Any]], *, keys: bool, depth: int) -> Iterator[str]:
    """The strings of ``(name, value)`` pairs: the names too when ``keys`` (a mapping's keys),
    never a value that is viser's own setting for its field."""
    for name, value in fields:
        if keys and isinstance(name, str):
            yield name
        if isinstance(name, str) and isinstance(value, str) and is_viser_setting(name, value):
            continue
        yield from iter_strings(value, _depth=depth + 1)


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

    def __init__(self, *, words: Iterable[str], block: bool = True) -> None:
        self.words = tuple(w.lower() for w in words)
        if not self.words or not all(self.words):
            raise ValueError("a blinding guard needs a non-empty list of non-empty words")
        self.block = block
        self.violations: list[Violation] = []
        """The first ``MAX_KEPT`` violations (``blocked`` counts them all)."""
        self.blocked = 0
        self.echoes = 0
        """Echoes of a tab's own typing dropped unread (:func:`is_own_echo`): never sent,
        never logged (a participant's text stays out of the server log)."""
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
            found = find_words(text, self.words)
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

    def on_queue(self, message: Any, *, own_echo: bool) -> bool:
        """A message the server is queueing (:class:`~study.server.viser_door.OutgoingWatch`):
        False drops it. A tab's own echo is dropped unread: what a participant typed is data,
        not a leak (a free-text answer may well hold a condition word), and viser would only
        hold this copy of it in the buffer unsent."""
        if own_echo:
            with self._lock:
                self.echoes += 1
            return False
        return self.allow(message)

    def on_serialize(self, out: dict[str, Any], *, message_type: str) -> dict[str, Any]:
        """A message's outgoing dict: ``out``, or a copy with every string naming a condition
        blanked (:meth:`redact`)."""
        with self._lock:
            self.serialized += 1
        if any(find_words(t, self.words) for t in iter_strings(out)):
            return self.redact(out, message_type=message_type)
        return out

    def redact(self, obj: Any, *, message_type: str) -> Any:
        """``obj`` (a serialisable dict tree) with every string naming a condition blanked."""
        if isinstance(obj, str):
            found = find_words(obj, self.words)
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
                k: v
                if isinstance(v, str) and is_viser_setting(k, v)
                else self.redact(v, message_type=message_type)
                for k, v in obj.items()
                if not (isinstance(k, str) and find_words(k, self.words))
            }
        if isinstance(obj, list | tuple):
            return type(obj)(self.redact(v, message_type=message_type) for v in obj)
        return obj


def install(server: viser.ViserServer, *, words: Iterable[str]) -> BlindingGuard:
    """Guard every message ``server`` sends from now on against ``words`` (the served
    protocol's :attr:`~study.protocol.Protocol.condition_words`); return the guard."""
    guard = BlindingGuard(words=words)
    viser_door.watch_outgoing(server, guard)
    return guard


def uninstall(server: viser.ViserServer) -> None:
    """Stop guarding ``server`` (call when it stops)."""
    viser_door.unwatch_outgoing(server)

"""The blinded vocabulary: every word that would tell a participant which condition they are in.

A protocol's vocabulary is the fixed list :data:`FIXED_WORDS` plus every level of every factor
it declares, every task name and every mode name, lower-cased, without repeats (computed once,
when the protocol is loaded: :attr:`study.protocol.Protocol.condition_words`). The loader
rejects a participant-facing text that contains one of these words (as a word or inside one:
"bright" holds "right"), and the study server's wire guard blocks every message that carries
one, for the protocol it serves.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

FIXED_WORDS: tuple[str, ...] = ("timid", "aggressive", "right", "wrong", "easy", "hard")
"""The paper's condition names, blinded in every protocol, even one whose levels are named
otherwise: they are the words an experimenter (or a participant who read the paper) would use
for a condition, so no participant-facing text may use them either."""


def blinded_words(
    factors: Mapping[str, Iterable[str]], *, tasks: Iterable[str], modes: Iterable[str]
) -> tuple[str, ...]:
    """:data:`FIXED_WORDS`, then every factor level, task name and mode name, lower-cased and
    without repeats (first occurrence kept)."""
    words: dict[str, None] = dict.fromkeys(FIXED_WORDS)
    for levels in factors.values():
        words.update(dict.fromkeys(w.lower() for w in levels))
    words.update(dict.fromkeys(w.lower() for w in tasks))
    words.update(dict.fromkeys(w.lower() for w in modes))
    return tuple(words)


def find_words(text: str, words: Iterable[str]) -> list[str]:
    """The ``words`` occurring in ``text`` (case-insensitive substrings, so "Bright" holds
    "right"), in the order of ``words``."""
    low = text.lower()
    return [w for w in words if w in low]
